#include "flowvid/optim/annealing.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/optim/cmaes.hpp"

#include "flowvid/random.hpp"
#include "search_result.hpp"
#include "timing.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <stdexcept>

namespace flowvid::optim {

const char* status_name(AnnealingResult::Status status) {
    switch (status) {
        case AnnealingResult::Status::converged: return "converged";
        case AnnealingResult::Status::max_evaluations: return "max_evaluations";
        case AnnealingResult::Status::time_budget: return "time_budget";
        case AnnealingResult::Status::cancelled: return "cancelled";
        case AnnealingResult::Status::no_finite_value: return "no_finite_value";
    }
    return "unknown";
}

const char* search_method_name(SearchMethod method) {
    switch (method) {
        case SearchMethod::annealing: return "annealing";
        case SearchMethod::cmaes: return "cmaes";
    }
    return "unknown";
}

std::optional<SearchMethod> search_method_from_name(std::string_view name) {
    for (const SearchMethod method : {SearchMethod::annealing, SearchMethod::cmaes})
        if (name == search_method_name(method)) return method;
    return std::nullopt;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

using detail::Clock;
using detail::progress_message;
using detail::seconds_since;

// The simplex and the search state of one run.
class Annealer {
public:
    Annealer(Evaluator& evaluator, const AnnealingSettings& settings, int run)
        : m_ev(evaluator), m_s(settings), m_random(settings.seed), m_n(evaluator.space().size()), m_run(run),
          m_start(Clock::now()) {
        if (m_n < 1) throw std::invalid_argument("anneal: the parameter space is empty");
        if (!(settings.cooling > 0.0 && settings.cooling < 1.0)) throw std::invalid_argument("anneal: cooling must be in (0, 1)");
        if (!(settings.reset_factor > 1.0)) throw std::invalid_argument("anneal: reset_factor must be > 1");
        if (!(settings.initial_step > 0.0)) throw std::invalid_argument("anneal: initial_step must be > 0");
        m_per_stage = settings.evaluations_per_stage > 0 ? settings.evaluations_per_stage : 10 * (m_n + 1);
        m_cooling = settings.cooling;
        if (settings.fit_schedule_to_budget && settings.max_evaluations > 0) {
            const double stages = std::max(1.0, 0.75 * static_cast<double>(settings.max_evaluations) / m_per_stage);
            m_cooling = std::pow(settings.final_temperature_ratio, 1.0 / stages);
        }
    }

    AnnealingResult run(const Eigen::VectorXd& start_unit, double start_value, double start_spread) {
        AnnealingResult r;
        if (start_unit.size() != m_n) throw std::invalid_argument("anneal: start has the wrong dimension");
        const long long before = m_ev.evaluations();
        m_best = start_unit;
        AnnealingResult::Status status = AnnealingResult::Status::converged;
        bool done = false;
        // The start and the first simplex are one indivisible step: a budget
        // that cannot pay for it ends the run before it starts.
        if (!affordable(m_n + (std::isnan(start_value) ? 1 : 0))) {
            status = AnnealingResult::Status::time_budget;
            done = true;
            m_best_value = start_value;
        } else {
            m_best_value = std::isnan(start_value) ? evaluate(start_unit) : start_value;
            build_simplex(m_best, m_best_value, m_s.initial_step);
        }
        r.start_value = m_best_value;

        // Temperature scale: the design's spread, else the initial simplex's.
        double spread = start_spread;
        if (!(spread > 0.0)) spread = finite_spread(m_y);
        m_t0 = m_s.initial_temperature >= 0.0 ? m_s.initial_temperature : m_s.temperature_scale * spread;
        if (!std::isfinite(m_t0) || m_t0 < 0.0) m_t0 = 0.0;
        m_t = m_t0;
        m_t_reset = m_t0;
        r.initial_temperature = m_t0;

        while (!done) {
            const long long stage_start = used();
            while (used() - stage_start < m_per_stage) {
                if (const auto stop = limit_reached()) {
                    status = *stop;
                    done = true;
                    break;
                }
                if (m_t == 0.0 && converged()) {
                    done = true;
                    break;
                }
                move();
                ++m_iterations;
            }
            ++m_stages;
            m_history.push_back({used(), m_t, m_best_value});
            if (!report_progress()) {
                status = AnnealingResult::Status::cancelled;
                done = true;
            }
            if (done) break;
            if (m_t > 0.0) {
                m_t *= m_cooling;
                if (m_t < m_t0 * m_s.final_temperature_ratio) {
                    // Polish: plain simplex from the best point with a small simplex.
                    m_t = 0.0;
                    if (!rebuild_at_best(std::max(m_s.min_step, m_s.initial_step * std::sqrt(m_s.final_temperature_ratio)))) {
                        status = AnnealingResult::Status::time_budget;
                        break;
                    }
                } else if (m_t <= m_t_reset / m_s.reset_factor) {
                    m_t_reset = m_t;
                    if (!rebuild_at_best(std::max(m_s.min_step, m_s.initial_step * std::pow(m_t / m_t0, m_s.step_exponent)))) {
                        status = AnnealingResult::Status::time_budget;
                        break;
                    }
                }
            }
        }
        detail::close_result(r, status, m_best, m_best_value, m_ev.space());
        r.evaluations = m_ev.evaluations() - before;
        r.iterations = m_iterations;
        r.stages = m_stages;
        r.resets = m_resets;
        r.final_temperature = m_t;
        r.elapsed_s = seconds_since(m_start);
        r.history = std::move(m_history);
        return r;
    }

private:
    long long used() const { return m_used; }

    double evaluate(const Eigen::VectorXd& p) {
        ++m_used;
        const double y = m_ev.evaluate(p);
        note(p, y);
        return y;
    }

    void note(const Eigen::VectorXd& p, double y) {
        if (y < m_best_value) {
            m_best = p;
            m_best_value = y;
        }
    }

    static double finite_spread(const std::vector<double>& values) {
        double sum = 0.0, sum2 = 0.0;
        int n = 0;
        for (double v : values)
            if (std::isfinite(v)) {
                sum += v;
                sum2 += v * v;
                ++n;
            }
        if (n < 2) return 0.0;
        const double mean = sum / n;
        return std::sqrt(std::max(0.0, sum2 / n - mean * mean));
    }

    // Vertex 0 is `centre` (value known); vertex i steps along axis i - 1,
    // towards the inside of the cube when the step would leave it.
    void build_simplex(const Eigen::VectorXd& centre, double centre_value, double step) {
        m_p.assign(static_cast<std::size_t>(m_n + 1), centre);
        m_y.assign(static_cast<std::size_t>(m_n + 1), centre_value);
        std::vector<Eigen::VectorXd> batch;
        for (int i = 0; i < m_n; ++i) {
            Eigen::VectorXd v = centre;
            v(i) += v(i) + step <= 1.0 ? step : -step;
            m_p[static_cast<std::size_t>(i + 1)] = v;
            batch.push_back(v);
        }
        const std::vector<double> values = m_ev.evaluate(batch);
        m_used += static_cast<long long>(batch.size());
        for (int i = 0; i < m_n; ++i) {
            m_y[static_cast<std::size_t>(i + 1)] = values[static_cast<std::size_t>(i)];
            note(batch[static_cast<std::size_t>(i)], values[static_cast<std::size_t>(i)]);
        }
    }

    // False (and nothing evaluated) when the budget cannot pay for a new simplex.
    bool rebuild_at_best(double step) {
        if (!affordable(m_n)) return false;
        ++m_resets;
        const Eigen::VectorXd centre = m_best;
        build_simplex(centre, m_best_value, step);
        return true;
    }

    // Whether `evaluations` more evaluations fit in the time budget, at the
    // run's measured pace (the hint before it has one).
    bool affordable(long long evaluations) const {
        if (!(m_s.budget_seconds > 0.0)) return true;
        const double elapsed = seconds_since(m_start);
        const double per_evaluation = used() > 0 ? elapsed / static_cast<double>(used()) : m_s.evaluation_seconds_hint;
        return elapsed + per_evaluation * static_cast<double>(evaluations) <= m_s.budget_seconds;
    }

    // One amebsa-style move: reflect the (fluctuated) worst vertex through the
    // centroid of the others, then expand, contract or shrink.
    void move() {
        const std::size_t count = m_p.size();
        m_fluctuated.resize(count);
        for (std::size_t i = 0; i < count; ++i) m_fluctuated[i] = m_y[i] + thermal();
        std::size_t lo = 0, hi = 0;
        for (std::size_t i = 1; i < count; ++i) {
            if (m_fluctuated[i] < m_fluctuated[lo]) lo = i;
            if (m_fluctuated[i] > m_fluctuated[hi]) hi = i;
        }
        std::size_t next_hi = hi == 0 ? 1 : 0;
        for (std::size_t i = 0; i < count; ++i)
            if (i != hi && m_fluctuated[i] > m_fluctuated[next_hi]) next_hi = i;
        double y_hi = m_fluctuated[hi];
        const double y_lo = m_fluctuated[lo], y_next = m_fluctuated[next_hi];

        Eigen::VectorXd centroid = Eigen::VectorXd::Zero(m_n);
        for (std::size_t i = 0; i < count; ++i)
            if (i != hi) centroid += m_p[i];
        centroid /= static_cast<double>(m_n);

        // Trial point centroid + factor (worst - centroid); replaces the worst
        // vertex when its (lowered) value beats the worst's (raised) one.
        auto trial = [&](double factor) {
            const Eigen::VectorXd p = centroid + factor * (m_p[hi] - centroid);
            const double y = evaluate(p);
            const double lowered = y - thermal();
            if (lowered < y_hi) {
                m_p[hi] = p;
                m_y[hi] = y;
                y_hi = lowered;
            }
            return lowered;
        };
        const double reflected = trial(-1.0);
        if (reflected <= y_lo) {
            trial(2.0);
        } else if (reflected >= y_next) {
            const double saved = y_hi;
            const double contracted = trial(0.5);
            if (contracted >= saved) shrink(lo);
        }
    }

    void shrink(std::size_t lo) {
        if (!affordable(m_n)) return;  // out of time: the next limit check ends the run
        std::vector<Eigen::VectorXd> batch;
        std::vector<std::size_t> which;
        for (std::size_t i = 0; i < m_p.size(); ++i) {
            if (i == lo) continue;
            m_p[i] = 0.5 * (m_p[i] + m_p[lo]);
            batch.push_back(m_p[i]);
            which.push_back(i);
        }
        const std::vector<double> values = m_ev.evaluate(batch);
        m_used += static_cast<long long>(batch.size());
        for (std::size_t k = 0; k < which.size(); ++k) {
            m_y[which[k]] = values[k];
            note(batch[k], values[k]);
        }
    }

    // T |log u|: exponentially distributed with mean T (0 when T = 0; the
    // random number is drawn anyway so the sequence never depends on T).
    double thermal() {
        const double u = m_random.open_unit();
        return m_t > 0.0 ? -m_t * std::log(u) : 0.0;
    }

    bool converged() const {
        double lo = kInf, hi = -kInf;
        for (double y : m_y) {
            lo = std::min(lo, y);
            hi = std::max(hi, y);
        }
        if (std::isfinite(lo) && std::isfinite(hi) &&
            2.0 * std::abs(hi - lo) <= m_s.tolerance * (std::abs(hi) + std::abs(lo) + 1e-12))
            return true;
        double size = 0.0;
        for (const Eigen::VectorXd& p : m_p) size = std::max(size, (p - m_p[0]).cwiseAbs().maxCoeff());
        return size < m_s.step_tolerance;
    }

    std::optional<AnnealingResult::Status> limit_reached() const {
        if (m_s.cancel && m_s.cancel->load()) return AnnealingResult::Status::cancelled;
        if (m_s.max_evaluations > 0 && used() >= m_s.max_evaluations) return AnnealingResult::Status::max_evaluations;
        // A move costs one to three evaluations, two as a rule.
        if (!affordable(2)) return AnnealingResult::Status::time_budget;
        return std::nullopt;
    }

    bool report_progress() {
        if (!m_s.progress) return true;
        const double elapsed_s = seconds_since(m_start);
        // Evaluations the schedule still needs: the stages down to the final
        // temperature, plus a polish of about as many as one stage.
        double remaining = static_cast<double>(m_per_stage);
        if (m_t > 0.0 && m_t0 > 0.0) {
            const double stages = std::log(m_t / (m_t0 * m_s.final_temperature_ratio)) / -std::log(m_cooling);
            remaining += std::max(0.0, stages) * m_per_stage;
        }
        if (m_s.max_evaluations > 0) remaining = std::min(remaining, static_cast<double>(m_s.max_evaluations - used()));
        remaining = std::max(remaining, 0.0);
        const double per_evaluation = used() > 0 ? elapsed_s / static_cast<double>(used()) : 0.0;
        double eta_s = remaining * per_evaluation;
        if (m_s.budget_seconds > 0.0) eta_s = std::min(eta_s, std::max(0.0, m_s.budget_seconds - elapsed_s));
        const double fraction = elapsed_s + eta_s > 0.0 ? elapsed_s / (elapsed_s + eta_s) : 0.0;
        return m_s.progress({"annealing", fraction, progress_message(used(), m_best_value, "T", m_t, eta_s)});
    }

    Evaluator& m_ev;
    const AnnealingSettings& m_s;
    Random m_random;
    int m_n;
    int m_run;
    Clock::time_point m_start;
    int m_per_stage = 0;
    double m_cooling = 0.9;
    std::vector<Eigen::VectorXd> m_p;
    std::vector<double> m_y;
    std::vector<double> m_fluctuated;
    Eigen::VectorXd m_best;
    double m_best_value = kInf;
    double m_t0 = 0.0, m_t = 0.0, m_t_reset = 0.0;
    long long m_used = 0;
    int m_iterations = 0, m_stages = 0, m_resets = 0;
    std::vector<AnnealingStage> m_history;
};

}  // namespace

AnnealingResult anneal(Evaluator& evaluator, const Eigen::VectorXd& start_unit, const AnnealingSettings& settings,
                       double start_value, double start_spread, int run) {
    Annealer annealer(evaluator, settings, run);
    return annealer.run(start_unit, start_value, start_spread);
}

MinimizeResult minimize(const Objective& objective, const ParameterSpace& space, const MinimizeSettings& settings) {
    ThreadPool pool(settings.threads);
    Evaluator evaluator(objective, space, &pool);
    const int n = space.size();
    std::vector<Eigen::VectorXd> points =
        settings.design == DesignKind::grid
            ? grid_design(n, settings.grid_levels)
            : halton_design(n, settings.design_points > 0 ? settings.design_points : 16 * n,
                            derive_seed(settings.annealing.seed, 0x4a17));
    MinimizeResult result;
    result.design_points_total = static_cast<int>(points.size());
    // A shard keeps every shard_count-th point of the whole design: the
    // shards together evaluate exactly the design an unsharded search does.
    const bool sharded = settings.shard_count > 0;
    if (sharded) {
        if (settings.shard_index < 1 || settings.shard_index > settings.shard_count)
            throw std::invalid_argument("minimize: shard " + std::to_string(settings.shard_index) + " of " +
                                        std::to_string(settings.shard_count) + " is out of 1.." +
                                        std::to_string(settings.shard_count));
        if (static_cast<std::size_t>(settings.shard_count) > points.size())
            throw std::invalid_argument("minimize: " + std::to_string(settings.shard_count) + " shards of a design of " +
                                        std::to_string(points.size()) + " points");
        std::vector<Eigen::VectorXd> own;
        for (std::size_t k = static_cast<std::size_t>(settings.shard_index - 1); k < points.size();
             k += static_cast<std::size_t>(settings.shard_count))
            own.push_back(std::move(points[k]));
        points = std::move(own);
    }
    // The design stops at an external cancel or, when it has one, its time budget.
    std::atomic<bool> design_stop{false};
    std::atomic<bool> design_done{false};
    std::thread watcher;
    if (settings.design_budget_seconds > 0.0 || settings.annealing.cancel) {
        watcher = std::thread([&] {
            const auto start = std::chrono::steady_clock::now();
            while (!design_done.load()) {
                const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                if ((settings.annealing.cancel && settings.annealing.cancel->load()) ||
                    (settings.design_budget_seconds > 0.0 && elapsed > settings.design_budget_seconds))
                    design_stop = true;
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
        });
    }
    const auto design_start = std::chrono::steady_clock::now();
    result.design = evaluate_design(evaluator, settings.design, std::move(points), &design_stop);
    const double design_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - design_start).count();
    design_done = true;
    if (watcher.joinable()) watcher.join();
    // Only an external cancel cancels; a design cut short by its budget goes on.
    result.design.cancelled = settings.annealing.cancel && settings.annealing.cancel->load();
    if (!std::isfinite(result.design.best_value())) result.design.cancelled = true;
    if (result.design.cancelled) {
        result.annealing.status = AnnealingResult::Status::cancelled;
        result.annealing.reason = "cancelled during the design";
        result.annealing.best_unit = result.design.points[result.design.best];
        result.annealing.best_values = space.to_values(result.annealing.best_unit);
        result.annealing.best_value = result.design.best_value();
        result.evaluations = evaluator.evaluations();
        return result;
    }
    AnnealingSettings annealing = settings.annealing;
    const long long design_evaluated = evaluator.evaluations();
    // A shard's annealing is charged the whole design, as the unsharded
    // search's is: the other shards evaluate the rest of it.
    const long long design_charged =
        design_evaluated + (result.design_points_total - static_cast<long long>(result.design.points.size()));
    if (sharded) annealing.seed = derive_seed(settings.annealing.seed, 0x5a4d0000ULL + settings.shard_index);
    if (settings.total_budget_seconds > 0.0)
        annealing.budget_seconds = std::max(1.0, settings.total_budget_seconds - design_seconds);
    if (annealing.max_evaluations > 0)
        annealing.max_evaluations = std::max<long long>(1, annealing.max_evaluations - design_charged);
    if (annealing.evaluation_seconds_hint <= 0.0 && design_evaluated > 0)
        annealing.evaluation_seconds_hint = design_seconds / static_cast<double>(design_evaluated);
    if (settings.method == SearchMethod::cmaes) {
        // CMA-ES evaluates whole generations in parallel, like the design:
        // its pace per point is the design's, and it needs no schedule.
        CmaesSettings strategy;
        strategy.seed = derive_seed(annealing.seed, 0xc3a5);
        strategy.population = settings.cmaes_population;
        strategy.initial_sigma = settings.cmaes_initial_sigma;
        strategy.max_evaluations = annealing.max_evaluations;
        strategy.budget_seconds = annealing.budget_seconds;
        strategy.evaluation_seconds_hint = design_evaluated > 0 ? design_seconds / static_cast<double>(design_evaluated) *
                                                                   static_cast<double>(evaluator.threads())
                                                             : annealing.evaluation_seconds_hint;
        strategy.progress = annealing.progress;
        strategy.cancel = annealing.cancel;
        const bool from_known = settings.cmaes_known_unit.size() == space.size() &&
                                settings.cmaes_known_value < result.design.best_value();
        result.annealing = cmaes(evaluator, from_known ? settings.cmaes_known_unit : result.design.points[result.design.best],
                                 strategy, from_known ? settings.cmaes_known_value : result.design.best_value());
        result.evaluations = evaluator.evaluations();
        return result;
    }
    // A time budget with a budget-fitted schedule: plan the cooling for the
    // evaluations that fit in the time left, so that the search ends cooled
    // rather than cut off hot. A simplex step is one evaluation at a time
    // (its objective may use the spare threads), so it is taken as 1.5x the
    // design's wall time per point.
    if (annealing.budget_seconds > 0.0 && annealing.fit_schedule_to_budget && design_evaluated > 0) {
        const double per_evaluation = 1.5 * design_seconds / static_cast<double>(design_evaluated);
        const long long affordable = static_cast<long long>(annealing.budget_seconds / std::max(per_evaluation, 1e-9));
        annealing.max_evaluations = std::clamp<long long>(affordable, 4LL * (space.size() + 1), std::max<long long>(annealing.max_evaluations, 4LL * (space.size() + 1)));
    }
    result.annealing = anneal(evaluator, result.design.points[result.design.best], annealing, result.design.best_value(),
                              result.design.spread());
    result.evaluations = evaluator.evaluations();
    return result;
}

VariabilityReport variability_analysis(const Objective& objective, const ParameterSpace& space,
                                       const Eigen::VectorXd& start_values, const VariabilitySettings& settings) {
    if (start_values.size() != space.size()) throw std::invalid_argument("variability_analysis: start has the wrong dimension");
    if (settings.runs < 1) throw std::invalid_argument("variability_analysis: runs must be >= 1");
    VariabilityReport report;
    Random random(derive_seed(settings.annealing.seed, 0x7a41));
    for (int i = 0; i < settings.runs; ++i) {
        Eigen::VectorXd start = start_values;
        for (int k = 0; k < space.size(); ++k) start(k) *= 1.0 + settings.perturbation * random.symmetric();
        report.starts.push_back(space.clamp_values(start));
    }
    report.runs.resize(static_cast<std::size_t>(settings.runs));

    // Runs in parallel, each on one worker: every run's numbers depend only
    // on its own seed, never on which thread runs it.
    ThreadPool pool(std::min(resolve_thread_count(settings.threads), settings.runs));
    std::mutex progress_mutex;
    pool.run(static_cast<std::size_t>(settings.runs), [&](std::size_t i, int worker) {
        Evaluator evaluator(objective, space, nullptr);
        evaluator.run_inline_as(worker);
        AnnealingSettings s = settings.annealing;
        s.seed = derive_seed(settings.annealing.seed, i + 1);
        if (settings.annealing.progress) {
            s.progress = [&, i](const ProgressReport& p) {
                std::lock_guard<std::mutex> lock(progress_mutex);
                return settings.annealing.progress({"variability", p.fraction, "run " + std::to_string(i + 1) + ": " + p.message});
            };
        }
        report.runs[i] = anneal(evaluator, space.to_unit(report.starts[i]), s, std::numeric_limits<double>::quiet_NaN(),
                                settings.start_spread, static_cast<int>(i));
    });

    report.best_value = kInf;
    report.worst_value = -kInf;
    for (const AnnealingResult& r : report.runs) {
        report.best_value = std::min(report.best_value, r.best_value);
        report.worst_value = std::max(report.worst_value, r.best_value);
    }
    const double runs = static_cast<double>(settings.runs);
    for (int k = 0; k < space.size(); ++k) {
        ParameterVariability v;
        v.name = space[k].name;
        v.min = kInf;
        v.max = -kInf;
        double sum = 0.0, log_sum = 0.0;
        bool positive = true;
        for (const AnnealingResult& r : report.runs) {
            const double x = r.best_values(k);
            sum += x;
            v.min = std::min(v.min, x);
            v.max = std::max(v.max, x);
            positive = positive && x > 0.0;
            if (x > 0.0) log_sum += std::log(x);
        }
        v.mean = sum / runs;
        double squares = 0.0, log_squares = 0.0;
        for (const AnnealingResult& r : report.runs) {
            const double x = r.best_values(k);
            squares += (x - v.mean) * (x - v.mean);
            if (positive) log_squares += (std::log(x) - log_sum / runs) * (std::log(x) - log_sum / runs);
        }
        v.stddev = settings.runs > 1 ? std::sqrt(squares / (runs - 1.0)) : 0.0;
        v.variability_percent = v.mean != 0.0 ? 100.0 * v.stddev / std::abs(v.mean) : 0.0;
        v.log_stddev = positive && settings.runs > 1 ? std::sqrt(log_squares / (runs - 1.0)) : 0.0;
        report.parameters.push_back(v);
    }
    return report;
}

}  // namespace flowvid::optim
