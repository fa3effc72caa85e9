#include "flowvid/optim/test_functions.hpp"

#include "flowvid/random.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace flowvid::optim {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

Eigen::VectorXd shift_of(int n, std::uint64_t seed, double half_width) {
    Eigen::VectorXd shift = Eigen::VectorXd::Zero(n);
    if (seed == 0) return shift;
    Random random(derive_seed(seed, 0x5eed));
    for (int i = 0; i < n; ++i) shift(i) = half_width * random.symmetric();
    return shift;
}

ParameterSpace box(int n, double half_width) {
    std::vector<Parameter> parameters;
    for (int i = 0; i < n; ++i) {
        std::string name = "x";  // (not "x" + ...: GCC 12 warns falsely about that)
        name += std::to_string(i);
        parameters.push_back({name, -half_width, half_width, false});
    }
    return ParameterSpace(parameters);
}

}  // namespace

TestFunction rastrigin(int n, std::uint64_t shift_seed) {
    TestFunction t;
    t.name = "rastrigin";
    t.name += std::to_string(n);
    t.space = box(n, 5.12);
    t.minimizer = shift_of(n, shift_seed, 4.0);
    const Eigen::VectorXd shift = t.minimizer;
    t.f = [shift](const Eigen::VectorXd& x) {
        double sum = 10.0 * static_cast<double>(x.size());
        for (Eigen::Index i = 0; i < x.size(); ++i) {
            const double z = x(i) - shift(i);
            sum += z * z - 10.0 * std::cos(kTwoPi * z);
        }
        return sum;
    };
    t.minimum = 0.0;
    t.success_threshold = 0.5;  // the nearest other local minima are at ~1
    return t;
}

TestFunction rastrigin_low_dimensional(int n, int active, std::uint64_t shift_seed) {
    TestFunction t = rastrigin(n, shift_seed);
    t.name = "rastrigin";
    t.name += std::to_string(active);
    t.name += "in";
    t.name += std::to_string(n);
    const Eigen::VectorXd shift = t.minimizer;
    const Eigen::Index a = std::clamp<Eigen::Index>(active, 1, n);
    t.f = [shift, a](const Eigen::VectorXd& x) {
        double sum = 10.0 * static_cast<double>(a);
        for (Eigen::Index i = 0; i < x.size(); ++i) {
            const double z = x(i) - shift(i);
            if (i < a)
                sum += z * z - 10.0 * std::cos(kTwoPi * z);
            else
                sum += 0.1 * (z / 5.12) * (z / 5.12);
        }
        return sum;
    };
    return t;
}

TestFunction ackley(int n, std::uint64_t shift_seed) {
    TestFunction t;
    t.name = "ackley";
    t.name += std::to_string(n);
    t.space = box(n, 32.768);
    t.minimizer = shift_of(n, shift_seed, 25.0);
    const Eigen::VectorXd shift = t.minimizer;
    t.f = [shift](const Eigen::VectorXd& x) {
        double squares = 0.0, cosines = 0.0;
        const double n = static_cast<double>(x.size());
        for (Eigen::Index i = 0; i < x.size(); ++i) {
            const double z = x(i) - shift(i);
            squares += z * z;
            cosines += std::cos(kTwoPi * z);
        }
        return -20.0 * std::exp(-0.2 * std::sqrt(squares / n)) - std::exp(cosines / n) + 20.0 + std::numbers::e;
    };
    t.minimum = 0.0;
    t.success_threshold = 0.5;  // the first ring of local minima lies above ~2
    return t;
}

}  // namespace flowvid::optim
