// The diagonal order of thesis fig. 3.5b: which K particles each line
// repeats, and which of them are on the line at an output frame.
#include "flowvid/flow/synthesis.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

namespace flowvid::flow {

namespace {

long long floor_div(long long a, long long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
long long positive_mod(long long a, long long b) { return ((a % b) + b) % b; }

std::uint64_t mix_seed(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ULL;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
    return x ^ (x >> 31);
}

// How well a window's wrap joins: the ladder step of fig. 3.5b. After each
// wrap the first particle of the window (start s) enters behind the last ones
// of the period before, which show input frames a period P later; where that
// particle is at age a, the input itself showed frame s + P + a. The error is
// the RMS difference of linear luma between its texture there and the texture
// of the input particle nearest that place at that frame (within a quarter
// patch), over the middle half of the patch, averaged over the lines and ages
// the clip has such a frame for. A fire whose flames are low at s + P shows
// the dark pot there in old particles beside the new ones' flames; a window
// whose wrap lands on similar frames hides the step, as the thesis expects.
class WrapJoin {
public:
    WrapJoin(const formats::ParticleBank& bank, const std::vector<const std::vector<std::pair<int, int>>*>& starts_by_line)
        : m_bank(bank), m_starts(starts_by_line) {
        const std::size_t frames = static_cast<std::size_t>(std::max(1, bank.clip_frame_count));
        m_alive.resize(starts_by_line.size(), std::vector<std::vector<std::pair<int, int>>>(frames));
        for (std::size_t l = 0; l < starts_by_line.size(); ++l)
            for (const auto& [start, index] : *starts_by_line[l]) {
                const formats::TrackedParticle& p = bank.particles[static_cast<std::size_t>(index)];
                for (int age = 0; age < p.life_frames(); ++age) {
                    const long long f = static_cast<long long>(start) + age;
                    if (f >= 0 && f < static_cast<long long>(frames)) m_alive[l][static_cast<std::size_t>(f)].emplace_back(index, age);
                }
            }
    }

    // NaN when nothing could be compared.
    double error(int s0, int step, int count) const {
        const int period = step * count, frames = static_cast<int>(m_alive.empty() ? 0 : m_alive.front().size());
        const int n = m_bank.patch_size_px;
        double sum = 0.0;
        long long samples = 0;
        for (std::size_t l = 0; l < m_starts.size(); ++l) {
            // The window's first particle on this line (an empty slot 0 leaves it to slot 1, ...).
            const auto& starts = *m_starts[l];
            const auto it = std::find_if(starts.begin(), starts.end(), [&](const std::pair<int, int>& st) {
                return st.first >= s0 && st.first < s0 + period && (st.first - s0) % step == 0;
            });
            if (it == starts.end()) continue;
            const formats::TrackedParticle& p = m_bank.particles[static_cast<std::size_t>(it->second)];
            for (int age = 0; age < p.life_frames(); ++age) {
                const int f = it->first + period + age;
                if (f >= frames) break;
                const float s = p.arc_length_px[static_cast<std::size_t>(age)];
                const std::pair<int, int>* nearest = nullptr;
                float nearest_px = static_cast<float>(n) / 4.0f;
                for (const auto& alive : m_alive[l][static_cast<std::size_t>(f)]) {
                    const float d = std::fabs(m_bank.particles[static_cast<std::size_t>(alive.first)].arc_length_px[static_cast<std::size_t>(alive.second)] - s);
                    if (d <= nearest_px) {
                        nearest_px = d;
                        nearest = &alive;
                    }
                }
                if (!nearest) continue;
                const double mse = middle_luma_mse(p, age, m_bank.particles[static_cast<std::size_t>(nearest->first)], nearest->second, n);
                if (std::isnan(mse)) continue;
                sum += mse;
                ++samples;
            }
        }
        return samples > 0 ? std::sqrt(sum / static_cast<double>(samples)) : std::numeric_limits<double>::quiet_NaN();
    }

private:
    static double middle_luma_mse(const formats::TrackedParticle& a, int age_a, const formats::TrackedParticle& b, int age_b, int n) {
        const std::size_t patch_values = static_cast<std::size_t>(n) * n * 4;
        const float* pa = a.texture_rgba.data() + static_cast<std::size_t>(age_a) * patch_values;
        const float* pb = b.texture_rgba.data() + static_cast<std::size_t>(age_b) * patch_values;
        const auto luma = [](const float* px) { return (0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]) / px[3]; };
        double sum = 0.0;
        int count = 0;
        for (int y = n / 4; y < n - n / 4; ++y)
            for (int x = n / 4; x < n - n / 4; ++x) {
                const std::size_t o = (static_cast<std::size_t>(y) * n + x) * 4;
                if (pa[o + 3] < 0.5f || pb[o + 3] < 0.5f) continue;  // outside the clip
                const double d = luma(pa + o) - luma(pb + o);
                sum += d * d;
                ++count;
            }
        return count > 0 ? sum / count : std::numeric_limits<double>::quiet_NaN();
    }

    const formats::ParticleBank& m_bank;
    std::vector<const std::vector<std::pair<int, int>>*> m_starts;         // per line: (start, particle), sorted
    std::vector<std::vector<std::vector<std::pair<int, int>>>> m_alive;  // per line, per input frame: (particle, age)
};

}  // namespace

// ---- schedule ----------------------------------------------------------------------------------

std::string some_line_ids(const std::vector<std::string>& ids) {
    std::string text;
    for (std::size_t i = 0; i < ids.size() && i < 3; ++i) text += (i ? ", " : "") + ids[i];
    if (ids.size() > 3) text += ", ...";
    return text;
}

Schedule make_schedule(const formats::ParticleBank& bank, const SynthesisSettings& settings) {
    Schedule schedule;
    std::map<std::string, std::vector<std::pair<int, int>>> by_line;  // id -> (start, particle index)
    for (std::size_t i = 0; i < bank.particles.size(); ++i)
        by_line[bank.particles[i].line_id].emplace_back(bank.particles[i].start_frame, static_cast<int>(i));
    std::vector<const formats::BankFlowLine*> lines;
    std::vector<std::string> empty_lines;
    for (const formats::BankFlowLine& line : bank.lines) {
        auto it = by_line.find(line.id);
        if (it == by_line.end() || it->second.empty()) {
            empty_lines.push_back(line.id);
            continue;
        }
        std::sort(it->second.begin(), it->second.end());
        lines.push_back(&line);
    }
    if (lines.empty()) throw std::invalid_argument("the bank has no particle to synthesize from");
    // Summaries, not one warning per line: a densified bank has hundreds.
    if (!empty_lines.empty())
        schedule.warnings.push_back(std::to_string(empty_lines.size()) + " of " + std::to_string(bank.lines.size()) +
                                    " lines have no tracked particle and are not synthesized (" + some_line_ids(empty_lines) + ")");

    int step = 0;
    int first_start = std::numeric_limits<int>::max(), last_start = std::numeric_limits<int>::min();
    for (const auto* line : lines) {
        const auto& starts = by_line[line->id];
        for (std::size_t i = 1; i < starts.size(); ++i) {
            const int d = starts[i].first - starts[i - 1].first;
            if (d > 0 && (step == 0 || d < step)) step = d;
        }
        first_start = std::min(first_start, starts.front().first);
        last_start = std::max(last_start, starts.back().first);
    }
    if (step == 0) step = 1;
    // Which start slots (first_start + i * step) each line has a particle for.
    const int slots = (last_start - first_start) / step + 1;
    std::vector<std::vector<int>> has(lines.size(), std::vector<int>(static_cast<std::size_t>(slots) + 1, 0));  // prefix counts
    for (std::size_t l = 0; l < lines.size(); ++l) {
        std::vector<int> present(static_cast<std::size_t>(slots), 0);
        for (const auto& [start, index] : by_line[lines[l]->id])
            if ((start - first_start) % step == 0) present[static_cast<std::size_t>((start - first_start) / step)] = 1;
        for (int i = 0; i < slots; ++i)
            has[l][static_cast<std::size_t>(i) + 1] = has[l][static_cast<std::size_t>(i)] + present[static_cast<std::size_t>(i)];
    }
    const auto missing = [&](int first_slot, int count) {
        int total = 0;
        for (const auto& prefix : has)
            total += count - (prefix[static_cast<std::size_t>(first_slot + count)] - prefix[static_cast<std::size_t>(first_slot)]);
        return total;
    };
    // The window: as many particles as possible while at most a quarter of
    // the slots (over all lines) lack a tracked particle of their own start
    // frame (they borrow a near start or stay empty, below), and every slot
    // has a particle to show (its own or a near one to borrow) on most lines.
    // A slot most lines lack is not a particle lost here and there but a gap
    // across the whole flow at once: typically the clip's last starts, whose
    // particles cannot complete their paths before it ends; each period its
    // entry would leave the lines' starts to the background everywhere for a
    // particle's life.
    constexpr double kMaxMissingShare = 0.25;
    const int line_count = static_cast<int>(lines.size());
    std::vector<int> thin_before(static_cast<std::size_t>(slots) + 1, 0);  // prefix counts of slots most lines lack
    for (int i = 0; i < slots; ++i) {
        const int target = first_start + i * step;
        int shown = 0;
        for (const auto* line : lines) {
            const auto& starts = by_line[line->id];
            const auto it = std::lower_bound(starts.begin(), starts.end(), std::make_pair(target - settings.borrow_within_frames, -1));
            if (it != starts.end() && it->first <= target + settings.borrow_within_frames) ++shown;
        }
        thin_before[static_cast<std::size_t>(i) + 1] = thin_before[static_cast<std::size_t>(i)] + (2 * shown < line_count ? 1 : 0);
    }
    // Should no window fit (no start frame on most lines), one particle: the
    // start most lines have.
    int k = 1, first_slot = 0;
    for (int f = 1; f < slots; ++f)
        if (missing(f, 1) < missing(first_slot, 1)) first_slot = f;
    const int wanted = settings.particles > 0 ? std::min(settings.particles, slots) : 0;
    if (settings.particles > slots)
        schedule.warnings.push_back("asked for " + std::to_string(settings.particles) + " particles per line but the bank spans only " +
                                    std::to_string(slots) + " start frames; using " + std::to_string(slots));
    const auto fits = [&](int f, int count) {
        const bool has_thin_slot = thin_before[static_cast<std::size_t>(f + count)] != thin_before[static_cast<std::size_t>(f)];
        return missing(f, count) <= kMaxMissingShare * count * line_count && !has_thin_slot;
    };
    std::vector<int> fitting;  // of the window found: its first slots with the fewest missing
    for (int count = wanted > 0 ? wanted : slots; count >= 1; --count) {
        fitting.clear();
        int best_missing = std::numeric_limits<int>::max();
        for (int f = 0; f + count <= slots; ++f) {
            const int m = missing(f, count);
            if (wanted == 0 && !fits(f, count)) continue;
            if (m < best_missing) {
                best_missing = m;
                fitting.clear();
            }
            if (m == best_missing) fitting.push_back(f);
        }
        if (fitting.empty()) continue;
        k = count;
        first_slot = fitting.front();
        if (settings.first_start_frame >= 0) {
            int nearest = fitting.front();
            for (int f = 0; f + count <= slots; ++f)
                if (std::abs(first_start + f * step - settings.first_start_frame) < std::abs(first_start + nearest * step - settings.first_start_frame))
                    nearest = f;
            first_slot = nearest;
            if (first_start + nearest * step != settings.first_start_frame)
                schedule.warnings.push_back("first start frame " + std::to_string(settings.first_start_frame) + " moved to " +
                                            std::to_string(first_start + nearest * step));
        } else if (settings.seed != 0) {
            first_slot = fitting[static_cast<std::size_t>(mix_seed(settings.seed) % fitting.size())];
        }
        break;
    }
    // The default window (no start frame or seed asked for): of those at
    // least kMinPeriodShare as long as the longest (or of the asked length),
    // the one whose wrap joins best, when it joins clearly better than the
    // longest, earliest one (a shorter period repeats sooner; a join within
    // noise of the other is not worth it).
    constexpr double kMinPeriodShare = 0.85, kMinJoinGain = 0.9;
    std::vector<const std::vector<std::pair<int, int>>*> line_starts;
    for (const auto* line : lines) line_starts.push_back(&by_line[line->id]);
    const WrapJoin join(bank, line_starts);
    std::optional<double> chosen_join_error;  // measured while choosing the default window
    if (settings.first_start_frame < 0 && settings.seed == 0 && !fitting.empty()) {
        std::vector<std::pair<int, int>> candidates;  // (count, first slot)
        if (wanted > 0) {
            for (int f : fitting) candidates.emplace_back(k, f);
        } else {
            const int shortest = std::max(1, static_cast<int>(std::ceil(kMinPeriodShare * k)));
            for (int count = k; count >= shortest; --count)
                for (int f = 0; f + count <= slots; ++f)
                    if (fits(f, count)) candidates.emplace_back(count, f);
        }
        // Long clips with a small start spacing fit thousands of windows: an
        // even sample of them keeps the choice to a fraction of a second.
        constexpr std::size_t kMaxJoinCandidates = 256;
        if (candidates.size() > kMaxJoinCandidates) {
            std::vector<std::pair<int, int>> sampled;
            for (std::size_t i = 0; i < kMaxJoinCandidates; ++i) sampled.push_back(candidates[i * candidates.size() / kMaxJoinCandidates]);
            candidates = std::move(sampled);
        }
        const double longest = join.error(first_start + first_slot * step, step, k);
        std::pair<int, int> best{k, first_slot};
        double best_error = longest;
        for (const auto& [count, f] : candidates) {
            const double e = join.error(first_start + f * step, step, count);
            if (e < best_error) {  // false for NaN
                best_error = e;
                best = {count, f};
            }
        }
        chosen_join_error = longest;
        if (best != std::make_pair(k, first_slot) && best_error < kMinJoinGain * longest) {
            schedule.longest_window = {k, first_start + first_slot * step, longest};
            k = best.first;
            first_slot = best.second;
            chosen_join_error = best_error;
        }
    }
    const int s0 = first_start + first_slot * step;
    schedule.particles_per_line = k;
    schedule.start_every = step;
    schedule.first_start_frame = s0;
    schedule.period_frames = k * step;
    schedule.wrap_join_error = chosen_join_error ? *chosen_join_error : join.error(s0, step, k);
    for (const auto* line : lines) {
        const auto& starts = by_line[line->id];
        LineSchedule ls;
        ls.line_id = line->id;
        for (int i = 0; i < k; ++i) {
            const int target = s0 + i * step;
            const auto it = std::lower_bound(starts.begin(), starts.end(), std::make_pair(target, -1));
            int chosen;
            if (it != starts.end() && it->first == target) chosen = it->second;
            else {
                ++ls.substituted;
                // The nearest start (ties go to the earlier), if near enough.
                const auto nearest = it == starts.end()     ? std::prev(it)
                                     : it == starts.begin() ? it
                                     : (target - std::prev(it)->first <= it->first - target) ? std::prev(it)
                                                                                            : it;
                chosen = std::abs(nearest->first - target) <= settings.borrow_within_frames ? nearest->second : -1;
                if (chosen >= 0) ++ls.borrowed;
            }
            ls.particles.push_back(chosen);
            if (chosen >= 0) ls.max_life = std::max(ls.max_life, bank.particles[static_cast<std::size_t>(chosen)].life_frames());
        }
        schedule.lines.push_back(std::move(ls));
    }
    int substituted = 0, borrowed = 0;
    std::vector<std::string> affected;
    for (const LineSchedule& ls : schedule.lines) {
        substituted += ls.substituted;
        borrowed += ls.borrowed;
        if (ls.substituted > 0) affected.push_back(ls.line_id);
    }
    if (substituted > 0) {
        std::string what;
        if (borrowed > 0)
            what = std::to_string(borrowed) + " borrow a particle starting at most " + std::to_string(settings.borrow_within_frames) +
                   " frames away";
        if (substituted > borrowed)
            what += (what.empty() ? "" : ", ") + std::to_string(substituted - borrowed) +
                    " are left empty (their neighbours cover them)";
        schedule.warnings.push_back(std::to_string(substituted) + " of " + std::to_string(k * static_cast<int>(schedule.lines.size())) +
                                    " particle slots (on " + std::to_string(affected.size()) + " lines: " + some_line_ids(affected) +
                                    ") had no complete particle of their start frame: " + what);
    }
    return schedule;
}

std::vector<ScheduledParticle> scheduled_particles(const Schedule& schedule, const formats::ParticleBank& bank,
                                                   std::size_t line, int frame) {
    std::vector<ScheduledParticle> out;
    const LineSchedule& ls = schedule.lines.at(line);
    const long long step = schedule.start_every, k = schedule.particles_per_line;
    const long long t = static_cast<long long>(frame) - 1;
    const long long m_hi = floor_div(t, step);
    const long long m_lo = -floor_div(-(t - (ls.max_life - 1)), step);  // ceil
    for (long long m = m_hi; m >= m_lo; --m) {
        const int age = static_cast<int>(t - m * step);
        const int particle = ls.particles[static_cast<std::size_t>(positive_mod(m, k))];
        if (particle < 0) continue;  // an empty slot
        if (age < bank.particles[static_cast<std::size_t>(particle)].life_frames()) out.push_back({particle, age, static_cast<int>(positive_mod(m, k))});
    }
    return out;
}

}  // namespace flowvid::flow
