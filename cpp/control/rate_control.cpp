#include "rate_control.h"

#include <cmath>

#include "reference_arithmetic.h"

namespace cufund {

namespace ra = reference_arithmetic;

namespace {
// libm's pow, called (not folded into x * x by the compiler), as Python's float ** does.
double (*volatile libm_pow)(double, double) = ::pow;
}  // namespace

RateControl::RateControl(const QuadrotorParams& params, double d_cutoff_hz, double i_scale)
    : allocator_(params), J_(params.inertia), i_scale_(i_scale), dw_filter_(d_cutoff_hz) {}

void RateControl::reset() {
  rate_int.setZero();
  dw_filter_.reset();
}

AllocationResult RateControl::step(const Eigen::Vector3d& w_B, const Eigen::Vector3d& w_sp, double thrust, double dt) {
  const RateControlGains& g = gains_;
  const Eigen::Vector3d& dw_filt = dw_filter_.update(w_B, dt);
  Eigen::Vector3d e, alpha_cmd, torque;
  for (int i = 0; i < 3; ++i) {
    e[i] = w_sp[i] - w_B[i];
    alpha_cmd[i] = g.k_p[i] * e[i] + rate_int[i] - g.k_d[i] * dw_filt[i] + g.feed_forward * w_sp[i];
  }
  for (int i = 0; i < 3; ++i) {  // J alpha as numpy's matmul accumulates it (exact for a diagonal J)
    torque[i] = std::fma(J_(i, 2), alpha_cmd[2], std::fma(J_(i, 1), alpha_cmd[1], J_(i, 0) * alpha_cmd[0]));
  }
  const AllocationResult r = allocator_.allocate(thrust, torque);
  const double lim = g.integrator_limit;
  for (int i = 0; i < 3; ++i) {
    const double ei = e[i];
    const int sat = r.saturation[i + 1];
    if ((sat > 0 && ei > 0) || (sat < 0 && ei < 0)) continue;
    const double i_factor = ra::py_max(0.0, 1.0 - libm_pow(ei / i_scale_, 2.0));
    rate_int[i] = ra::clamp(rate_int[i] + i_factor * g.k_i[i] * ei * dt, -lim, lim);
  }
  return r;
}

}  // namespace cufund
