// Minimum-derivative splines through waypoints (Mellinger & Kumar 2011) and the optimisation of their segment
// times: the hot loop of the min-snap motion planner (python/cufund/planning/minimum_snap.py documents the maths).
#pragma once

#include <cstddef>
#include <vector>

namespace cufund::planning {

// Coefficients of the piecewise polynomial through `values` ((m + 1) x dim, row-major) that minimises
// int |p^(order)|^2 dt with segment times `durations` (m, each > 0), derivatives 1..order-1 zero at both
// ends: m x (2 order) x dim, row-major, in normalised time s = (t - t_i) / T_i in [0, 1]. The optimum is a
// degree 2 order - 1 spline continuous to derivative 2 order - 2: one banded linear system (partial pivoting).
std::vector<double> min_derivative_spline(const double* values, std::size_t m, std::size_t dim, const double* durations,
                                          int order);

// Snap cost J = sum_i int |p''''|^2 dt of the minimum-snap spline (order 4) through `values` ((m + 1) x dim),
// and (if grad is not null, size m) its exact gradient dJ/dT_i = -H_i (the segment's constant "energy").
double snap_cost_and_gradient(const double* values, std::size_t m, std::size_t dim, const double* durations,
                              double* grad);

struct TimeOptimizationResult {
  std::vector<double> durations;  // same total as the input
  int iterations = 0;
  int evaluations = 0;
};

// Segment times with the total of `durations` that minimise the snap cost: BFGS over log T on the scale-free
// objective log J(T) + 7 log sum T (J(a T) = a^-7 J(T)), exact gradient, backtracking Armijo line search; stops
// when the objective's gradient is below `gtol` (infinity norm) or after `max_iterations`. Never worse than
// the input. Deterministic.
TimeOptimizationResult optimize_segment_times(const double* values, std::size_t m, std::size_t dim,
                                              const double* durations, int max_iterations = 100, double gtol = 1e-6);

}  // namespace cufund::planning
