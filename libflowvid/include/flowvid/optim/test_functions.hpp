#pragma once
// Standard multimodal test functions for the optimizers (tests and
// bench/bench_optim.cpp), shifted so that the global minimum is not at the
// centre of the box or on a design grid: a seeded shift moves it to a random
// point well inside the bounds.
//
//  * Rastrigin: 10 n + sum (z^2 - 10 cos 2 pi z), box [-5.12, 5.12]^n, about
//    11^n local minima on a parabola; minimum 0.
//  * Ackley: -20 exp(-0.2 sqrt(mean z^2)) - exp(mean cos 2 pi z) + 20 + e,
//    box [-32.768, 32.768]^n, a nearly flat plateau of ripples around a
//    narrow funnel; minimum 0.
//  * Rastrigin of low effective dimension: Rastrigin in the first `active`
//    coordinates plus a shallow bowl 0.1 sum (z_i / 5.12)^2 in the others,
//    which barely matter. This is the shape of a cloth fit (thesis table
//    2.2: bend and stretch are well determined, damping hardly at all), and
//    where a grid is weakest: 4^n points show only 4 values of each
//    coordinate, so only 4^active distinct settings of what matters.
// with z = x - shift.

#include "flowvid/optim/parameter_space.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <string>

namespace flowvid::optim {

struct TestFunction {
    std::string name;
    ParameterSpace space;
    std::function<double(const Eigen::VectorXd& x)> f;
    Eigen::VectorXd minimizer;
    double minimum = 0.0;
    // Below this the run found the global minimum's basin (the next local
    // minimum lies above it).
    double success_threshold = 0.0;
};

// shift_seed 0: no shift (minimum at the origin).
TestFunction rastrigin(int dimensions, std::uint64_t shift_seed);
TestFunction ackley(int dimensions, std::uint64_t shift_seed);
TestFunction rastrigin_low_dimensional(int dimensions, int active, std::uint64_t shift_seed);

}  // namespace flowvid::optim
