// Control-point optimisation of a uniform cubic B-spline against an ESDF (the Fast-Planner /
// EGO-Planner family): smoothness + collision + feasibility (+ a pull of the horizon's end), by L-BFGS.
#pragma once

#include <vector>

#include "clearance.h"
#include "esdf_map.h"

namespace cufund::planning {

struct BsplineWeights {
  double smooth = 1.0;       // sum |Q_{i+3} - 3 Q_{i+2} + 3 Q_{i+1} - Q_i|^2 (jerk control points)
  double collision = 50.0;   // sum max(0, d_safe - d(Q_i))^3 over the free control points
  double feasibility = 1.0;  // squared excess of velocity / acceleration control points per axis
  double end = 10.0;         // |Q_last - end_target|^2 when pull_end
  double d_safe = 0.6;       // [m]
  double v_max = 2.0;        // [m/s]
  double a_max = 3.0;        // [m/s^2]
  double dt = 0.15;          // knot interval [s]
};

struct BsplineProblem {
  std::vector<Vec3> start;  // fixed leading control points (the state at the start)
  std::vector<Vec3> tail;   // fixed trailing control points (e.g. the goal three times), may be empty
  Vec3 end_target{0.0, 0.0, 0.0};
  bool pull_end = false;  // pull the last free control point to end_target
};

struct LbfgsOptions {
  int max_iterations = 200;
  int memory = 8;
  double gradient_tolerance = 1e-6;  // stop when |g|_inf <= this * max(1, |f|)
  double relative_decrease = 1e-6;   // or when an iteration lowers f by less than this * max(1, |f|)
};

struct BsplineResult {
  std::vector<Vec3> free;  // the optimised free control points
  double cost = 0.0;
  int iterations = 0;
  int evaluations = 0;
};

// The cost at free control points x (and its gradient into grad, if not null: same size as x).
double bspline_cost(const esdf::EsdfMap& map, const BsplineProblem& problem, const BsplineWeights& w,
                    const std::vector<Vec3>& x, std::vector<Vec3>* grad);

// L-BFGS with a backtracking (Armijo) line search from `initial`; deterministic.
BsplineResult optimize_bspline(const esdf::EsdfMap& map, const BsplineProblem& problem, const BsplineWeights& w,
                               const std::vector<Vec3>& initial, const LbfgsOptions& options);

}  // namespace cufund::planning
