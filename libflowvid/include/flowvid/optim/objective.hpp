#pragma once
// What the optimizers minimise, and how points are evaluated: one at a time
// (a simplex step) or in parallel batches (a space-filling design, a simplex
// reset or shrink) on a ThreadPool.
//
// An objective must be deterministic (the same values give the same number)
// and safe to call from several threads at once. The context says which
// worker calls it (for per-worker scratch such as renderers) and how many
// threads the objective may use inside itself: all of the pool's when it is
// evaluated alone, 1 inside a parallel batch. A cloth objective uses this to
// simulate its trials in parallel during simplex steps.
//
// Failed evaluations (a simulation that blew up) return +inf or NaN: both
// count as +inf. Points outside the unit cube are not evaluated and count
// as +inf (the box constraint).

#include "flowvid/optim/parameter_space.hpp"
#include "flowvid/thread_pool.hpp"

#include <Eigen/Core>

#include <atomic>
#include <functional>
#include <vector>

namespace flowvid::optim {

struct EvaluationContext {
    int worker = 0;         // in [0, pool threads)
    int spare_threads = 1;  // threads the objective may use itself
};

// Called with parameter *values* (not unit-cube coordinates).
using Objective = std::function<double(const Eigen::VectorXd& values, const EvaluationContext& context)>;

class Evaluator {
public:
    // `pool` may be null (everything on the calling thread as worker 0).
    Evaluator(Objective objective, ParameterSpace space, ThreadPool* pool = nullptr);

    const ParameterSpace& space() const { return m_space; }
    int threads() const { return m_pool ? m_pool->threads() : 1; }

    // One unit-cube point (on the calling thread, with all spare threads).
    double evaluate(const Eigen::VectorXd& unit);
    // A batch in parallel; values[i] belongs to points[i] whatever the thread count.
    // Points not started when `cancel` is set are skipped (value +inf).
    std::vector<double> evaluate(const std::vector<Eigen::VectorXd>& unit_points,
                                 const std::atomic<bool>* cancel = nullptr);

    // Points actually evaluated (points outside the cube are not counted).
    long long evaluations() const { return m_evaluations.load(); }

    // Evaluate on the calling thread as this worker, never in parallel: for
    // optimizer runs that are themselves spread over the pool's workers.
    void run_inline_as(int worker) { m_inline_worker = worker; }

private:
    double call(const Eigen::VectorXd& unit, const EvaluationContext& context);

    Objective m_objective;
    ParameterSpace m_space;
    ThreadPool* m_pool = nullptr;
    int m_inline_worker = -1;
    std::atomic<long long> m_evaluations{0};
};

}  // namespace flowvid::optim
