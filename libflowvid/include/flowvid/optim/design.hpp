#pragma once
// Space-filling designs that pick the optimizer's start (thesis 2.4.5: "we
// choose four values for each cloth parameter across its entire range ...
// 4^9 points", then start from the best). A full grid needs levels^n
// simulations; a scrambled Halton sequence covers the same box with any
// number of points, every one of them at a distinct value of every
// parameter (a grid repeats 4 values), so far fewer simulations find as
// good a start on rugged objectives (tests/unit/optim/test_design.cpp,
// bench/bench_optim.cpp).

#include "flowvid/optim/objective.hpp"

#include <Eigen/Core>

#include <atomic>
#include <cstdint>
#include <vector>

namespace flowvid::optim {

enum class DesignKind { grid, halton };
const char* design_name(DesignKind kind);

// Every combination of `levels` values per dimension at the centres of
// equal cells ((k + 0.5) / levels), in the unit cube. levels^dimensions
// points; throws std::invalid_argument beyond 10 million.
std::vector<Eigen::VectorXd> grid_design(int dimensions, int levels);

// `count` points of the Halton sequence (bases: the first primes), each
// digit of each dimension passed through its own random permutation drawn
// from `seed` (random digit scrambling, which removes the correlations of
// plain Halton between high dimensions). Deterministic for a seed; up to 32
// dimensions (std::invalid_argument beyond).
std::vector<Eigen::VectorXd> halton_design(int dimensions, int count, std::uint64_t seed);

struct DesignResult {
    DesignKind kind = DesignKind::halton;
    std::vector<Eigen::VectorXd> points;  // unit cube
    std::vector<double> values;           // +inf where failed or skipped (cancelled)
    std::size_t best = 0;                 // index of the lowest value (the first on ties)
    bool cancelled = false;

    double best_value() const;
    // Standard deviation of the finite values: a scale for the annealing temperature.
    double spread() const;
};

// Evaluates the points in parallel batches on the evaluator's pool. `cancel`
// (optional) is polled between batches of 4 x threads points.
DesignResult evaluate_design(Evaluator& evaluator, DesignKind kind, std::vector<Eigen::VectorXd> points,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace flowvid::optim
