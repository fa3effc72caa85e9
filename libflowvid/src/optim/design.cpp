#include "flowvid/optim/design.hpp"

#include "flowvid/random.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace flowvid::optim {

const char* design_name(DesignKind kind) { return kind == DesignKind::grid ? "grid" : "halton"; }

std::vector<Eigen::VectorXd> grid_design(int dimensions, int levels) {
    if (dimensions < 1 || levels < 1) throw std::invalid_argument("grid_design: dimensions and levels must be >= 1");
    double total = std::pow(static_cast<double>(levels), dimensions);
    if (total > 1e7) throw std::invalid_argument("grid_design: " + std::to_string(levels) + "^" + std::to_string(dimensions) +
                                                 " points is more than 10 million");
    const std::size_t count = static_cast<std::size_t>(total);
    std::vector<Eigen::VectorXd> points;
    points.reserve(count);
    std::vector<int> digit(static_cast<std::size_t>(dimensions), 0);
    for (std::size_t i = 0; i < count; ++i) {
        Eigen::VectorXd p(dimensions);
        for (int d = 0; d < dimensions; ++d) p(d) = (digit[static_cast<std::size_t>(d)] + 0.5) / levels;
        points.push_back(p);
        for (int d = 0; d < dimensions; ++d) {  // odometer
            if (++digit[static_cast<std::size_t>(d)] < levels) break;
            digit[static_cast<std::size_t>(d)] = 0;
        }
    }
    return points;
}

std::vector<Eigen::VectorXd> halton_design(int dimensions, int count, std::uint64_t seed) {
    static constexpr int kPrimes[32] = {2,  3,  5,  7,  11, 13, 17, 19, 23, 29, 31, 37, 41,  43,  47,  53,
                                        59, 61, 67, 71, 73, 79, 83, 89, 97, 101, 103, 107, 109, 113, 127, 131};
    if (dimensions < 1 || dimensions > 32) throw std::invalid_argument("halton_design: 1 to 32 dimensions");
    if (count < 0) throw std::invalid_argument("halton_design: negative count");
    Random random(seed);
    std::vector<Eigen::VectorXd> points(static_cast<std::size_t>(count), Eigen::VectorXd(dimensions));
    for (int d = 0; d < dimensions; ++d) {
        const int base = kPrimes[d];
        // Enough digits for double precision: base^digits >= 2^53.
        const int digits = static_cast<int>(std::ceil(53.0 * std::log(2.0) / std::log(static_cast<double>(base))));
        std::vector<std::vector<int>> permutation(static_cast<std::size_t>(digits), std::vector<int>(static_cast<std::size_t>(base)));
        for (auto& perm : permutation) {
            std::iota(perm.begin(), perm.end(), 0);
            for (int i = base - 1; i > 0; --i)  // Fisher-Yates with our own generator: portable
                std::swap(perm[static_cast<std::size_t>(i)], perm[static_cast<std::size_t>(random.below(static_cast<std::uint64_t>(i) + 1))]);
        }
        for (int i = 0; i < count; ++i) {
            long long n = i;
            double value = 0.0, scale = 1.0 / base;
            for (int k = 0; k < digits; ++k) {
                const int digit = static_cast<int>(n % base);
                n /= base;
                value += permutation[static_cast<std::size_t>(k)][static_cast<std::size_t>(digit)] * scale;
                scale /= base;
            }
            points[static_cast<std::size_t>(i)](d) = std::min(value, std::nextafter(1.0, 0.0));
        }
    }
    return points;
}

double DesignResult::best_value() const {
    return values.empty() ? std::numeric_limits<double>::infinity() : values[best];
}

double DesignResult::spread() const {
    double sum = 0.0, sum2 = 0.0;
    long long n = 0;
    for (double v : values)
        if (std::isfinite(v)) {
            sum += v;
            sum2 += v * v;
            ++n;
        }
    if (n < 2) return 0.0;
    const double mean = sum / static_cast<double>(n);
    return std::sqrt(std::max(0.0, sum2 / static_cast<double>(n) - mean * mean));
}

DesignResult evaluate_design(Evaluator& evaluator, DesignKind kind, std::vector<Eigen::VectorXd> points,
                             const std::atomic<bool>* cancel) {
    DesignResult result;
    result.kind = kind;
    result.points = std::move(points);
    result.values.assign(result.points.size(), std::numeric_limits<double>::infinity());
    // One batch for the whole design: evaluation costs vary a lot (a stiff
    // fabric's simulation takes several times a soft one's), and smaller
    // batches leave threads idle at every batch end. A cancel skips the rest.
    if (cancel && cancel->load()) {
        result.cancelled = true;
    } else {
        const std::vector<double> values = evaluator.evaluate(result.points, cancel);
        std::copy(values.begin(), values.end(), result.values.begin());
        result.cancelled = cancel && cancel->load();
    }
    for (std::size_t i = 0; i < result.values.size(); ++i)
        if (result.values[i] < result.values[result.best]) result.best = i;
    return result;
}

}  // namespace flowvid::optim
