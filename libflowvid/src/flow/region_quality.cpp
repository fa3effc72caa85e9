// The whole flow region's measures (quality.hpp, "the whole flow region"):
// the definitions of ../shared/tools/baselines_flow.py, so that `flowvid
// quality` shows what that tool scores, computed here in C++.

#include "flowvid/flow/quality.hpp"
#include "flowvid/random.hpp"

#include "series_statistics.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numeric>
#include <stdexcept>

namespace flowvid::flow {

using detail::mean_of;
using detail::percentile;

namespace {

// Population standard deviation over the mean, as numpy's std (the scoring
// tool's); quality.cpp's coefficient_of_variation divides by n - 1.
double cv_of(const std::vector<double>& v) {
    const double m = mean_of(v);
    if (v.size() < 2 || m <= 0.0) return 0.0;
    double s = 0.0;
    for (double x : v) s += (x - m) * (x - m);
    return std::sqrt(s / static_cast<double>(v.size())) / m;
}

// Mean |g(t+1) - g(t)| over the whole frame, grey levels.
std::vector<double> frame_transitions(const std::vector<std::vector<float>>& frames) {
    std::vector<double> d;
    for (std::size_t t = 0; t + 1 < frames.size(); ++t) {
        double sum = 0.0;
        for (std::size_t i = 0; i < frames[t].size(); ++i) sum += std::fabs(frames[t + 1][i] - frames[t][i]);
        d.push_back(255.0 * sum / static_cast<double>(std::max<std::size_t>(1, frames[t].size())));
    }
    return d;
}

// Mean |g(t+1) - g(t)| in the region of frame t+1.
std::vector<double> region_transitions(const std::vector<std::vector<float>>& frames,
                                       const std::vector<std::vector<std::uint8_t>>& regions) {
    std::vector<double> d;
    for (std::size_t t = 0; t + 1 < frames.size(); ++t) {
        const std::vector<std::uint8_t>& mask = regions[regions.size() == 1 ? 0 : t + 1];
        double sum = 0.0;
        std::size_t n = 0;
        for (std::size_t i = 0; i < mask.size(); ++i)
            if (mask[i]) {
                sum += std::fabs(frames[t + 1][i] - frames[t][i]);
                ++n;
            }
        d.push_back(n ? 255.0 * sum / static_cast<double>(n) : 0.0);
    }
    return d;
}

// Variance, over the region, of the 4-neighbour Laplacian (borders reflected
// without repeating the edge pixel, as OpenCV's default), grey levels.
double laplacian_variance(const std::vector<float>& g, int width, int height, const std::vector<std::uint8_t>& mask) {
    const auto reflect = [](int i, int n) { return i < 0 ? std::min(n - 1, -i) : (i >= n ? std::max(0, 2 * n - 2 - i) : i); };
    double sum = 0.0, sum2 = 0.0;
    std::size_t n = 0;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * width + x;
            if (!mask[i]) continue;
            const auto at = [&](int xx, int yy) {
                return g[static_cast<std::size_t>(reflect(yy, height)) * width + reflect(xx, width)];
            };
            const double l = 255.0 * (at(x - 1, y) + at(x + 1, y) + at(x, y - 1) + at(x, y + 1) - 4.0 * g[i]);
            sum += l;
            sum2 += l * l;
            ++n;
        }
    if (n == 0) return 0.0;
    const double m = sum / static_cast<double>(n);
    return std::max(0.0, sum2 / static_cast<double>(n) - m * m);
}

// Top-left corners on a `stride` grid whose patch centre lies in the mask.
std::vector<std::pair<int, int>> patch_grid(const std::vector<std::uint8_t>& mask, int width, int height, int patch,
                                            int stride) {
    std::vector<std::pair<int, int>> corners;
    for (int y = 0; y + patch <= height; y += stride)
        for (int x = 0; x + patch <= width; x += stride)
            if (mask[static_cast<std::size_t>(y + patch / 2) * width + x + patch / 2]) corners.emplace_back(x, y);
    return corners;
}

using PatchVector = Eigen::Matrix<float, Eigen::Dynamic, 1>;

// Grey levels quantised to 0..255, as the 8-bit frames the scoring tool reads.
PatchVector cut_patch(const std::vector<float>& g, int width, int x0, int y0, int patch) {
    PatchVector p(patch * patch);
    for (int y = 0; y < patch; ++y)
        for (int x = 0; x < patch; ++x) {
            const float v = g[static_cast<std::size_t>(y0 + y) * width + x0 + x];
            p[y * patch + x] = std::round(std::clamp(v, 0.0f, 1.0f) * 255.0f);
        }
    return p;
}

// The clip's patches with a PCA shortlist (32 components, 4 candidates): the
// nearest patch is the exact nearest of the 4 closest in PCA space.
class PatchDatabase {
    static constexpr Eigen::Index kBlockColumns = 4096;

public:
    PatchDatabase(const std::vector<std::vector<float>>& clip, const std::vector<int>& frames, int width, int height,
                  const std::vector<std::uint8_t>& region, const RegionSettings& s)
        : m_patch(s.patch_px) {
        const std::vector<std::pair<int, int>> grid = patch_grid(region, width, height, s.patch_px, s.search_stride_px);
        const int dims = s.patch_px * s.patch_px;
        m_raw.resize(dims, static_cast<Eigen::Index>(grid.size() * frames.size()));
        Eigen::Index column = 0;
        for (int f : frames)
            for (const auto& [x, y] : grid) {
                m_raw.col(column++) = cut_patch(clip[static_cast<std::size_t>(f)], width, x, y, s.patch_px).cast<std::uint8_t>();
                m_frame.push_back(f);
            }
        if (m_raw.cols() == 0) return;
        // PCA on up to 20 000 patches drawn with a fixed seed.
        Random rng(s.seed);
        const Eigen::Index sample = std::min<Eigen::Index>(20000, m_raw.cols());
        Eigen::MatrixXd chosen(dims, sample);
        for (Eigen::Index i = 0; i < sample; ++i)
            chosen.col(i) = m_raw.col(static_cast<Eigen::Index>(rng.below(static_cast<std::uint64_t>(m_raw.cols())))).cast<double>();
        const Eigen::VectorXd mean = chosen.rowwise().mean();
        chosen.colwise() -= mean;
        // The lower triangle only (half the products): the solver reads no more.
        Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(dims, dims);
        covariance.selfadjointView<Eigen::Lower>().rankUpdate(chosen, 1.0 / std::max<double>(1.0, static_cast<double>(sample - 1)));
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(covariance);
        const int components = std::min(32, dims);
        m_mean = mean.cast<float>();
        m_basis = solver.eigenvectors().rightCols(components).cast<float>();  // ascending order: the last are the largest
        // Projected a block of patches at a time: one matrix product each
        // streams the basis once, where a product per patch re-read it.
        m_projected.resize(components, m_raw.cols());
        for (Eigen::Index j0 = 0; j0 < m_raw.cols(); j0 += kBlockColumns) {
            const Eigen::Index n = std::min(kBlockColumns, m_raw.cols() - j0);
            Eigen::MatrixXf centred = m_raw.middleCols(j0, n).cast<float>();
            centred.colwise() -= m_mean;
            m_projected.middleCols(j0, n).noalias() = m_basis.transpose() * centred;
        }
        m_projected_norm = m_projected.colwise().squaredNorm().transpose();
    }

    bool empty() const { return m_raw.cols() == 0; }

    // RMS grey-level distance from each query (a column) to its nearest clip
    // patch, leaving out the patches of that query's `exclude_frames` entry
    // (-1: none). The shortlist of each query is its 4 smallest PCA-space
    // distances (ties: the earlier patch), found in one pass over the clip's
    // patches for all queries together: the patches stream through memory
    // once, in blocks, where a pass per query read them once each.
    std::vector<double> nearest(const Eigen::MatrixXf& queries, const std::vector<int>& exclude_frames) const {
        const Eigen::Index count = queries.cols();
        std::vector<double> distances(static_cast<std::size_t>(count), 0.0);
        if (count == 0) return distances;
        Eigen::MatrixXf centred = queries;
        centred.colwise() -= m_mean;
        const Eigen::MatrixXf projected = m_basis.transpose() * centred;  // components x queries
        constexpr int kShortlist = 4;
        using Candidate = std::pair<float, Eigen::Index>;
        std::vector<std::vector<Candidate>> best(static_cast<std::size_t>(count));
        Eigen::MatrixXf dots;
        for (Eigen::Index j0 = 0; j0 < m_projected.cols(); j0 += kBlockColumns) {
            const Eigen::Index n = std::min(kBlockColumns, m_projected.cols() - j0);
            dots.noalias() = m_projected.middleCols(j0, n).transpose() * projected;  // n x queries
            for (Eigen::Index q = 0; q < count; ++q) {
                std::vector<Candidate>& list = best[static_cast<std::size_t>(q)];
                const int exclude = exclude_frames[static_cast<std::size_t>(q)];
                for (Eigen::Index k = 0; k < n; ++k) {
                    const Eigen::Index j = j0 + k;
                    const float approx = m_projected_norm[j] - 2.0f * dots(k, q);
                    if (list.size() == kShortlist && !(approx < list.back().first)) continue;
                    if (m_frame[static_cast<std::size_t>(j)] == exclude) continue;
                    list.emplace_back(approx, j);
                    std::sort(list.begin(), list.end());
                    if (list.size() > kShortlist) list.pop_back();
                }
            }
        }
        for (Eigen::Index q = 0; q < count; ++q) {
            double nearest = std::numeric_limits<double>::infinity();
            for (const auto& [_, j] : best[static_cast<std::size_t>(q)])
                nearest = std::min(nearest, static_cast<double>((m_raw.col(j).cast<float>() - queries.col(q)).squaredNorm()));
            distances[static_cast<std::size_t>(q)] =
                std::isfinite(nearest) ? std::sqrt(nearest / static_cast<double>(queries.rows())) : 0.0;
        }
        return distances;
    }

private:
    int m_patch;
    // One patch per column, grey levels: 8 bits, as the tool's frames (a
    // quarter of floats' memory, which every clip frame's patches need).
    Eigen::Matrix<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic> m_raw;
    std::vector<int> m_frame;
    Eigen::VectorXf m_mean;
    Eigen::MatrixXf m_basis;
    Eigen::MatrixXf m_projected;
    Eigen::VectorXf m_projected_norm;
};

std::vector<int> spread(int count, int wanted) {
    std::vector<int> frames;
    if (count <= 0) return frames;
    wanted = std::clamp(wanted, 1, count);
    for (int k = 0; k < wanted; ++k) {
        const int f = wanted == 1 ? 0 : static_cast<int>(std::lround(static_cast<double>(k) * (count - 1) / (wanted - 1)));
        if (frames.empty() || frames.back() != f) frames.push_back(f);
    }
    return frames;
}

// Mean nearest-patch distance of the grid patches of `frames` of `sequence`,
// at most max_queries of them (drawn evenly).
double mean_patch_distance(const PatchDatabase& db, const std::vector<std::vector<float>>& sequence,
                           const std::vector<int>& frames, const std::vector<std::vector<std::uint8_t>>& regions, int width,
                           int height, const RegionSettings& s, bool leave_own_frame_out) {
    std::vector<std::pair<int, std::pair<int, int>>> queries;  // frame, corner
    for (int f : frames) {
        const std::vector<std::uint8_t>& mask = regions[regions.size() == 1 ? 0 : static_cast<std::size_t>(f)];
        for (const auto& corner : patch_grid(mask, width, height, s.patch_px, s.query_stride_px))
            queries.push_back({f, corner});
    }
    if (queries.empty() || db.empty()) return 0.0;
    const std::size_t step = std::max<std::size_t>(1, (queries.size() + s.max_queries - 1) / s.max_queries);
    std::vector<std::size_t> chosen;
    for (std::size_t i = 0; i < queries.size(); i += step) chosen.push_back(i);
    Eigen::MatrixXf patches(s.patch_px * s.patch_px, static_cast<Eigen::Index>(chosen.size()));
    std::vector<int> exclude;
    for (std::size_t c = 0; c < chosen.size(); ++c) {
        const auto& [f, corner] = queries[chosen[c]];
        patches.col(static_cast<Eigen::Index>(c)) =
            cut_patch(sequence[static_cast<std::size_t>(f)], width, corner.first, corner.second, s.patch_px);
        exclude.push_back(leave_own_frame_out ? f : -1);
    }
    double total = 0.0;
    for (double d : db.nearest(patches, exclude)) total += d;
    return total / static_cast<double>(chosen.size());
}

}  // namespace

double periodic_peak_share(const std::vector<double>& series, double min_period, double max_period) {
    const std::size_t n = series.size();
    if (n < 8) return 0.0;
    const double m = mean_of(series);
    double total = 0.0, peak = 0.0;
    for (std::size_t k = 1; k <= n / 2; ++k) {
        std::complex<double> x = 0.0;
        for (std::size_t t = 0; t < n; ++t)
            x += (series[t] - m) * std::polar(1.0, -2.0 * M_PI * static_cast<double>(k * t) / static_cast<double>(n));
        const double power = std::norm(x);
        total += power;
        const double period = static_cast<double>(n) / static_cast<double>(k);
        if (period >= min_period && period <= max_period) peak = std::max(peak, power);
    }
    return total > 0.0 ? peak / total : 0.0;
}

struct RegionMeter::Clip {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> region;
    RegionSettings settings;
    std::vector<double> transitions;
    double p99 = 0.0;
    std::vector<double> energy;
    double motion = 0.0;  // median region transition
    std::unique_ptr<PatchDatabase> patches;
    double loo_patch_rms = 0.0;
};

RegionMeter::RegionMeter(const std::vector<std::vector<float>>& clip_luma, int width, int height,
                         std::vector<std::uint8_t> clip_region, const RegionSettings& s)
    : m_clip(new Clip{width, height, std::move(clip_region), s}) {
    Clip& c = *m_clip;
    if (clip_luma.size() < 2) throw std::invalid_argument("the clip needs at least two frames to be measured against");
    c.transitions = frame_transitions(clip_luma);
    c.p99 = percentile(c.transitions, 0.99);
    for (const auto& g : clip_luma) c.energy.push_back(laplacian_variance(g, width, height, c.region));
    c.motion = percentile(region_transitions(clip_luma, {c.region}), 0.5);
    const int clip_count = static_cast<int>(clip_luma.size());
    const std::vector<int> search_frames = spread(clip_count, s.max_search_frames > 0 ? s.max_search_frames : clip_count);
    c.patches = std::make_unique<PatchDatabase>(clip_luma, search_frames, width, height, c.region, s);
    // Leave-one-frame-out queries come from searched frames, so that leaving one out means something.
    std::vector<int> queries;
    for (int k : spread(static_cast<int>(search_frames.size()), s.query_frames))
        queries.push_back(search_frames[static_cast<std::size_t>(k)]);
    c.loo_patch_rms = mean_patch_distance(*c.patches, clip_luma, queries, {c.region}, width, height, s, true);
}

RegionMeter::~RegionMeter() = default;

RegionQuality RegionMeter::measure(const std::vector<std::vector<float>>& output_luma,
                                   const std::vector<std::vector<std::uint8_t>>& output_regions,
                                   bool leave_own_frame_out) const {
    const Clip& c = *m_clip;
    if (output_luma.size() < 2) throw std::invalid_argument("the output needs at least two frames to be measured");
    if (leave_own_frame_out && output_luma.size() > c.energy.size())
        throw std::invalid_argument("leaving each output frame's own clip frame out needs at most the clip's frames");
    if (output_regions.size() != 1 && output_regions.size() != output_luma.size())
        throw std::invalid_argument("one output region, or one per output frame");
    RegionQuality q;
    q.clip_region_pixels = static_cast<std::size_t>(std::count(c.region.begin(), c.region.end(), 1));
    for (const auto& region : output_regions)
        q.output_region_pixels += static_cast<double>(std::count(region.begin(), region.end(), 1)) / output_regions.size();

    const std::vector<double> out_d = frame_transitions(output_luma);
    const auto share_above = [&c](const std::vector<double>& d) {
        return d.empty() ? 0.0
                         : static_cast<double>(std::count_if(d.begin(), d.end(), [&c](double x) { return x > c.p99; })) / d.size();
    };
    if (c.p99 > 0.0) {
        q.seam_max_ratio = *std::max_element(out_d.begin(), out_d.end()) / c.p99;
        q.clip_seam_max_ratio = *std::max_element(c.transitions.begin(), c.transitions.end()) / c.p99;
    }
    q.share_above_p99 = share_above(out_d);
    q.clip_share_above_p99 = share_above(c.transitions);

    std::vector<double> out_e;
    for (std::size_t t = 0; t < output_luma.size(); ++t)
        out_e.push_back(laplacian_variance(output_luma[t], c.width, c.height, output_regions[output_regions.size() == 1 ? 0 : t]));
    q.pulse_cv = cv_of(out_e);
    q.clip_pulse_cv = cv_of(c.energy);
    q.pulse_peak = periodic_peak_share(out_e);
    q.clip_pulse_peak = periodic_peak_share(c.energy);
    q.detail = mean_of(c.energy) > 0.0 ? mean_of(out_e) / mean_of(c.energy) : 0.0;
    q.motion = c.motion > 0.0 ? percentile(region_transitions(output_luma, output_regions), 0.5) / c.motion : 0.0;

    q.clip_patch_rms = c.loo_patch_rms;
    q.patch_rms = mean_patch_distance(*c.patches, output_luma, spread(static_cast<int>(output_luma.size()), c.settings.query_frames),
                                      output_regions, c.width, c.height, c.settings, leave_own_frame_out);
    q.patch_fidelity = q.clip_patch_rms > 0.0 ? q.patch_rms / q.clip_patch_rms : 0.0;
    return q;
}

double clip_detail_share(const std::vector<std::vector<float>>& clip_luma, int width, int height,
                         const std::vector<std::uint8_t>& region, const std::vector<std::uint8_t>& clip_region) {
    const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    if (region.size() != pixels || clip_region.size() != pixels)
        throw std::invalid_argument("clip_detail_share: the regions are not the clip's size");
    if (clip_luma.empty() || std::count(region.begin(), region.end(), 1) == 0) return 0.0;
    double over_region = 0.0, over_clip_region = 0.0;
    for (const auto& g : clip_luma) {
        over_region += laplacian_variance(g, width, height, region);
        over_clip_region += laplacian_variance(g, width, height, clip_region);
    }
    return over_clip_region > 0.0 ? over_region / over_clip_region : 0.0;
}

RegionQuality measure_region_quality(const std::vector<std::vector<float>>& clip_luma,
                                     const std::vector<std::vector<float>>& output_luma, int width, int height,
                                     const std::vector<std::uint8_t>& clip_region,
                                     const std::vector<std::vector<std::uint8_t>>& output_regions,
                                     const RegionSettings& settings) {
    return RegionMeter(clip_luma, width, height, clip_region, settings).measure(output_luma, output_regions);
}

}  // namespace flowvid::flow
