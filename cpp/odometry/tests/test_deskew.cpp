// Deskewing against a closed-form trajectory: constant velocity and constant yaw rate.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "deskew.h"
#include "imu_propagation.h"

namespace cufund::odometry {
namespace {

Eigen::Isometry3d make_pose(const Eigen::Vector3d& rotvec, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3_exp(rotvec);
  T.translation() = t;
  return T;
}

TEST(Deskew, EveryPointLandsWhereTheTrueMotionPutsIt) {
  const double w = 1.1, h = 0.005, t0 = 10.0;
  const Eigen::Vector3d v0(1.5, -0.5, 0.2);
  const std::size_t n_imu = 24;  // 0.12 s of knots around a 0.1 s frame
  std::vector<double> dt(n_imu, h), acc, gyr, states(10 * (n_imu + 1)), rates(6 * n_imu), knot_t(n_imu + 1);
  for (std::size_t k = 0; k < n_imu; ++k) {
    acc.insert(acc.end(), {0.0, 0.0, 9.81});
    gyr.insert(gyr.end(), {0.0, 0.0, w});
  }
  for (std::size_t k = 0; k <= n_imu; ++k) knot_t[k] = t0 + h * static_cast<double>(k);
  NavState s0;
  s0.v_W = v0;
  propagate(s0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -9.81), dt.data(), acc.data(),
            gyr.data(), n_imu, states.data(), rates.data());
  // The trajectory has one more knot than rate rows; the last state closes the last interval.
  const Trajectory traj{knot_t.data(), states.data(), rates.data(), n_imu + 1};

  const Eigen::Isometry3d T_BI = make_pose({0.1, -0.2, 0.3}, {0.02, 0.01, -0.03});
  const Eigen::Isometry3d T_BL = make_pose({0.0, 0.4, -0.1}, {0.1, 0.0, 0.08});
  const Eigen::Isometry3d T_IL = T_BI.inverse() * T_BL;
  auto T_WI = [&](double t) { return make_pose({0, 0, w * (t - t0)}, v0 * (t - t0)); };

  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-10.0, 10.0), ut(0.0, 0.1);
  const std::size_t n = 500;
  std::vector<float> pts(3 * n);
  std::vector<double> t_pts(n), truth(3 * n), out(3 * n);
  const double t_ref = t0 + 0.1;
  for (std::size_t i = 0; i < n; ++i) {
    t_pts[i] = t0 + ut(rng);
    for (int j = 0; j < 3; ++j) pts[3 * i + j] = static_cast<float>(u(rng));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x_L(static_cast<double>(pts[3 * i]), static_cast<double>(pts[3 * i + 1]),
                              static_cast<double>(pts[3 * i + 2]));
    Eigen::Map<Eigen::Vector3d>(truth.data() + 3 * i) = (T_WI(t_ref) * T_IL).inverse() * (T_WI(t_pts[i]) * T_IL * x_L);
  }
  deskew(pts.data(), t_pts.data(), n, traj, t_ref, T_BI, T_BL, out.data(), 2);
  double worst = 0.0;
  for (std::size_t i = 0; i < 3 * n; ++i) worst = std::max(worst, std::abs(out[i] - truth[i]));
  EXPECT_LT(worst, 1e-9);
  // And the distortion it removed was real (centimetres to decimetres).
  double moved = 0.0;
  for (std::size_t i = 0; i < 3 * n; ++i) moved = std::max(moved, std::abs(out[i] - pts[i]));
  EXPECT_GT(moved, 0.05);
}

}  // namespace
}  // namespace cufund::odometry
