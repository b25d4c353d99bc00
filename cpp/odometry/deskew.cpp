#include "deskew.h"

#include <algorithm>
#include <vector>

#include "imu_propagation.h"
#include "thread_pool.h"

namespace cufund::odometry {

namespace {

// pose_at with the knots' rotation matrices precomputed (R_knots may be null: from the quaternions).
void pose_at_impl(const Trajectory& traj, const Eigen::Matrix3d* R_knots, double tau, Eigen::Matrix3d& R_WI,
                  Eigen::Vector3d& p_W) {
  // Interval k: the last knot at or before tau, clamped to [0, K-2].
  const double* end = traj.knot_t + traj.knots;
  std::ptrdiff_t k = std::upper_bound(traj.knot_t, end, tau) - traj.knot_t - 1;
  k = std::clamp<std::ptrdiff_t>(k, 0, static_cast<std::ptrdiff_t>(traj.knots) - 2);
  const double* s = traj.states + 10 * k;
  const double* r = traj.rates + 6 * k;
  const double h = tau - traj.knot_t[k];
  const Eigen::Vector3d w(r[3], r[4], r[5]);
  const Eigen::Matrix3d R_k =
      R_knots ? R_knots[k] : Eigen::Quaterniond(s[6], s[7], s[8], s[9]).normalized().toRotationMatrix();
  R_WI = R_k * so3_exp(w * h);
  p_W = Eigen::Vector3d(s[0], s[1], s[2]) + Eigen::Vector3d(s[3], s[4], s[5]) * h +
        Eigen::Vector3d(r[0], r[1], r[2]) * (0.5 * h * h);
}

}  // namespace

void pose_at(const Trajectory& traj, double tau, Eigen::Matrix3d& R_WI, Eigen::Vector3d& p_W) {
  pose_at_impl(traj, nullptr, tau, R_WI, p_W);
}

void deskew(const float* points_L, const double* t_points, std::size_t n, const Trajectory& traj, double t_ref,
            const Eigen::Isometry3d& T_BI, const Eigen::Isometry3d& T_BL, double* out, int threads) {
  const Eigen::Isometry3d T_IL = T_BI.inverse() * T_BL;
  Eigen::Matrix3d R_ref;
  Eigen::Vector3d p_ref;
  pose_at(traj, t_ref, R_ref, p_ref);
  Eigen::Isometry3d T_WI_ref = Eigen::Isometry3d::Identity();
  T_WI_ref.linear() = R_ref;
  T_WI_ref.translation() = p_ref;
  const Eigen::Isometry3d T_LW_ref = T_IL.inverse() * T_WI_ref.inverse();
  const Eigen::Matrix3d R_LW = T_LW_ref.linear();
  const Eigen::Vector3d t_LW = T_LW_ref.translation();
  // Per interval k, everything the points of the interval share, already in the LiDAR frame at t_ref:
  //   x_out = A_k Exp(w_k s) x_I + b_k + c_k s + d_k s^2,  A_k = R_LW R_k,  b_k = R_LW p_k + t_LW,
  //   c_k = R_LW v_k,  d_k = R_LW a_k / 2;  Exp(phi) x by Rodrigues' formula on the vector (no matrix).
  struct Interval {
    Eigen::Matrix3d A;
    Eigen::Vector3d b, c, d, w;
  };
  const std::size_t K = traj.knots;
  std::vector<Interval> iv(K - 1);
  for (std::size_t k = 0; k + 1 < K; ++k) {
    const double* s = traj.states + 10 * k;
    const double* r = traj.rates + 6 * k;
    const Eigen::Matrix3d R_k = Eigen::Quaterniond(s[6], s[7], s[8], s[9]).normalized().toRotationMatrix();
    iv[k].A = R_LW * R_k;
    iv[k].b = R_LW * Eigen::Vector3d(s[0], s[1], s[2]) + t_LW;
    iv[k].c = R_LW * Eigen::Vector3d(s[3], s[4], s[5]);
    iv[k].d = R_LW * Eigen::Vector3d(r[0], r[1], r[2]) * 0.5;
    iv[k].w = Eigen::Vector3d(r[3], r[4], r[5]);
  }
  const double* kt = traj.knot_t;
  const auto last = static_cast<std::ptrdiff_t>(K) - 2;
  parallel_chunks(
      static_cast<std::ptrdiff_t>(n), 4096, threads, [&](std::ptrdiff_t b, std::ptrdiff_t e, std::ptrdiff_t) {
        std::ptrdiff_t k = -1;
        for (std::ptrdiff_t i = b; i < e; ++i) {
          const double tau = t_points[i];
          // Interval: the last knot at or before tau, clamped to [0, K-2]; kept from the previous point while it
          // still holds (the points of a frame come in time order).
          if (k < 0 || !((k == 0 || tau >= kt[k]) && (k == last || tau < kt[k + 1]))) {
            k = std::upper_bound(kt, kt + K, tau) - kt - 1;
            k = std::clamp<std::ptrdiff_t>(k, 0, last);
          }
          const Interval& I = iv[static_cast<std::size_t>(k)];
          const double h = tau - kt[k];
          const Eigen::Vector3d x_I = T_IL * Eigen::Vector3d(points_L[3 * i], points_L[3 * i + 1], points_L[3 * i + 2]);
          const Eigen::Vector3d phi = I.w * h;
          const double t2 = phi.squaredNorm();
          const Eigen::Vector3d px = phi.cross(x_I), ppx = phi.cross(px);
          Eigen::Vector3d rx;
          if (t2 < 1e-16) {
            rx = x_I + px + 0.5 * ppx;
          } else {
            const double t = std::sqrt(t2);
            rx = x_I + (std::sin(t) / t) * px + ((1.0 - std::cos(t)) / t2) * ppx;
          }
          Eigen::Map<Eigen::Vector3d>(out + 3 * i) = I.A * rx + I.b + I.c * h + I.d * (h * h);
        }
      });
}

}  // namespace cufund::odometry
