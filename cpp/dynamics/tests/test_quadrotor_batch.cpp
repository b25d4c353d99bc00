#include <gtest/gtest.h>

#include <thread>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <random>

#include "mixer.h"
#include "quadrotor_batch.h"
#include "test_helpers.h"

namespace cufund {
namespace {

using testing::run;
using testing::set_row;
using testing::small_quad;
using B = QuadrotorBatch;

Eigen::Quaterniond attitude(const B& b, std::size_t i = 0) {
  return Eigen::Quaterniond(b.row(B::kQ)[i], b.row(B::kQ + 1)[i], b.row(B::kQ + 2)[i], b.row(B::kQ + 3)[i]);
}
Eigen::Vector3d vec(const B& b, int field, std::size_t i = 0) {
  return Eigen::Vector3d(b.row(field)[i], b.row(field + 1)[i], b.row(field + 2)[i]);
}

TEST(QuadrotorBatch, FreeFallMatchesHalfGTSquared) {
  B b(small_quad(), 1);
  set_row(b, B::kP, {1.0, -2.0, 100.0});
  const double g = b.params().gravity;
  run(b, 1e-3, 3000, {0, 0, 0, 0});
  const double t = 3.0;
  // RK4 integrates the constant-acceleration polynomial exactly: only rounding remains.
  EXPECT_NEAR(b.row(B::kP + 2)[0], 100.0 - 0.5 * g * t * t, 1e-9);
  EXPECT_NEAR(b.row(B::kV + 2)[0], -g * t, 1e-11);
  EXPECT_EQ(b.row(B::kP)[0], 1.0);
  EXPECT_EQ(b.row(B::kP + 1)[0], -2.0);
  EXPECT_EQ(vec(b, B::kAccel), Eigen::Vector3d(0, 0, -g));
  EXPECT_EQ(vec(b, B::kAlpha), Eigen::Vector3d::Zero());
}

TEST(QuadrotorBatch, HoverAtAnalyticSpeedStaysWithinMicrometre) {
  for (RotorLayout layout : {RotorLayout::kX, RotorLayout::kPlus}) {
    QuadrotorParams p = small_quad();
    p.layout = layout;
    p.rotor_drag_xy = 1e-6;  // drag at zero airspeed must not matter
    p.body_drag = Eigen::Vector3d(0.01, 0.01, 0.02);
    B b(p, 1);
    const double wh = b.hover_rotor_speed();
    EXPECT_NEAR(4 * p.k_f * wh * wh, p.mass * p.gravity, 1e-15);
    set_row(b, B::kP, {0.0, 0.0, 1.5});
    set_row(b, B::kRotor, {wh, wh, wh, wh});
    run(b, 1e-3, 10000, {wh, wh, wh, wh});
    EXPECT_LT((vec(b, B::kP) - Eigen::Vector3d(0, 0, 1.5)).norm(), 1e-6);
    EXPECT_LT(vec(b, B::kW).norm(), 1e-9);
    EXPECT_NEAR(b.time(), 10.0, 1e-9);
  }
}

TEST(QuadrotorBatch, TorqueFreeSpinConservesMomentumAndEnergy) {
  QuadrotorParams p = small_quad();
  // A full, non-diagonal inertia so that the motion is a genuine tumble (J is SPD).
  p.inertia << 1.43e-5, 2.0e-7, -1.0e-7, 2.0e-7, 1.60e-5, 3.0e-7, -1.0e-7, 3.0e-7, 2.89e-5;
  p.gravity = 0.0;
  B b(p, 1);
  set_row(b, B::kP, {0, 0, 10});
  set_row(b, B::kW, {3.0, -2.0, 5.0});
  auto momentum_W = [&] { return Eigen::Vector3d(attitude(b).toRotationMatrix() * (p.inertia * vec(b, B::kW))); };
  auto energy = [&] { return 0.5 * vec(b, B::kW).dot(p.inertia * vec(b, B::kW)); };
  const Eigen::Vector3d L0 = momentum_W();
  const double E0 = energy();
  double worst_L = 0, worst_E = 0;
  for (int k = 0; k < 10; ++k) {
    run(b, 1e-3, 1000, {0, 0, 0, 0});
    worst_L = std::max(worst_L, (momentum_W() - L0).norm() / L0.norm());
    worst_E = std::max(worst_E, std::abs(energy() - E0) / E0);
  }
  // RK4's global error over T = 10 s at h = 1 ms is O(T |w| (h |w|)^4) ~ 10 * 6 * (6e-3)^4 ~ 8e-8 relative;
  // the tolerance is that bound. A sign error in w x Jw or in the quaternion kinematics gives O(1).
  EXPECT_LT(worst_L, 1e-7);
  EXPECT_LT(worst_E, 1e-7);
  EXPECT_GT(vec(b, B::kW).norm(), 1.0);  // still spinning
}

TEST(QuadrotorBatch, MotorStepFollowsFirstOrderLag) {
  QuadrotorParams p = small_quad();
  p.ground_plane = false;
  B b(p, 1);
  const double target = 2000.0;
  for (int k = 1; k <= 300; ++k) {
    run(b, 1e-3, 1, {target, target, target, 3000.0});  // rotor 4 commanded beyond the limit
    const double t = k * 1e-3;
    EXPECT_NEAR(b.row(B::kRotor)[0], target * (1 - std::exp(-t / p.tau_m)), 1e-8 * target);
    EXPECT_NEAR(b.row(B::kRotor + 3)[0], p.rotor_speed_max * (1 - std::exp(-t / p.tau_m)), 1e-8 * target);
  }
}

TEST(QuadrotorBatch, AngularAccelerationIsMixerMomentThroughInertia) {
  for (RotorLayout layout : {RotorLayout::kX, RotorLayout::kPlus}) {
    QuadrotorParams p = small_quad();
    p.layout = layout;
    p.gravity = 0.0;
    p.tau_m = 1e6;  // rotor speeds effectively frozen over the step
    B b(p, 1);
    set_row(b, B::kP, {0, 0, 5});
    const double w[4] = {1700, 1900, 1800, 1600};
    set_row(b, B::kRotor, {w[0], w[1], w[2], w[3]});
    Vector4d f;
    for (int i = 0; i < 4; ++i) f(i) = p.k_f * w[i] * w[i];
    const Vector4d wrench = allocation_matrix(p) * f;
    const double dt = 1e-6;
    run(b, dt, 1, {w[0], w[1], w[2], w[3]});
    const Eigen::Vector3d alpha = vec(b, B::kW) / dt;
    const Eigen::Vector3d expected = p.inertia.inverse() * wrench.tail<3>();
    EXPECT_LT((alpha - expected).norm(), 1e-6 * expected.norm());
    EXPECT_LT((vec(b, B::kAlpha) - expected).norm(), 1e-6 * expected.norm());
    EXPECT_NEAR(b.row(B::kAccel + 2)[0], wrench(0) / p.mass, 1e-6 * wrench(0) / p.mass);
    EXPECT_NEAR(b.row(B::kV + 2)[0] / dt, wrench(0) / p.mass, 1e-6 * wrench(0) / p.mass);
  }
}

TEST(QuadrotorBatch, BodyDragGivesAnalyticTerminalVelocity) {
  QuadrotorParams p = small_quad();
  p.body_drag = Eigen::Vector3d(0.0, 0.0, 0.004);
  p.ground_plane = false;
  B b(p, 1);
  run(b, 1e-3, 20000, {0, 0, 0, 0});
  EXPECT_NEAR(b.row(B::kV + 2)[0], -std::sqrt(p.mass * p.gravity / p.body_drag.z()), 1e-6);
}

TEST(QuadrotorBatch, RotorDragPushesHoveringVehicleDownwind) {
  QuadrotorParams p = small_quad();
  p.rotor_drag_xy = 1.0e-6;
  B b(p, 1);
  const double wh = b.hover_rotor_speed();
  set_row(b, B::kP, {0, 0, 2});
  set_row(b, B::kRotor, {wh, wh, wh, wh});
  set_row(b, B::kWind, {2.0, 0.0, 0.0});
  const double dt = 1e-5;
  run(b, dt, 1, {wh, wh, wh, wh});
  // H = -sum_i omega_i k_d (v - wind) = 4 omega_h k_d * wind at rest.
  EXPECT_NEAR(b.row(B::kV)[0] / dt, 4 * wh * p.rotor_drag_xy * 2.0 / p.mass, 1e-6);
}

TEST(QuadrotorBatch, GroundHoldsLandedVehicleAndAllowsTakeOff) {
  B b(small_quad(), 1);
  set_row(b, B::kP, {0.3, 0.2, 0.5});
  set_row(b, B::kV, {0.5, 0.0, 0.0});
  set_row(b, B::kW, {0.5, -0.3, 0.2});
  for (int k = 0; k < 2000; ++k) {
    run(b, 1e-3, 1, {0, 0, 0, 0});
    ASSERT_GE(b.row(B::kP + 2)[0], 0.0) << "fell through the ground at step " << k;
  }
  EXPECT_EQ(b.row(B::kP + 2)[0], 0.0);
  EXPECT_EQ(vec(b, B::kV).norm(), 0.0);
  EXPECT_EQ(vec(b, B::kW).norm(), 0.0);
  EXPECT_EQ(vec(b, B::kAccel).norm(), 0.0);  // the ground holds it: nothing accelerates
  // Resting level (yaw kept): body z along world z.
  EXPECT_NEAR((attitude(b).toRotationMatrix().col(2) - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  // Idle rotors below hover speed keep it down; above, it climbs.
  const double wh = b.hover_rotor_speed();
  run(b, 1e-3, 500, {0.9 * wh, 0.9 * wh, 0.9 * wh, 0.9 * wh});
  EXPECT_EQ(b.row(B::kP + 2)[0], 0.0);
  run(b, 1e-3, 1000, {1.2 * wh, 1.2 * wh, 1.2 * wh, 1.2 * wh});
  EXPECT_GT(b.row(B::kP + 2)[0], 0.05);
}

TEST(QuadrotorBatch, TiltedGroundHoldsVehicleAtThePadAttitudeWithItsYaw) {
  QuadrotorParams p = small_quad();
  const Eigen::Quaterniond pad(Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(0.6, 0.8, 0.0)));
  p.ground_attitude = Eigen::Vector4d(pad.w(), pad.x(), pad.y(), pad.z());
  B b(p, 1);
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond q0 = pad * yaw;
  set_row(b, B::kQ, {q0.w(), q0.x(), q0.y(), q0.z()});
  set_row(b, B::kP, {0.0, 0.0, 0.2});  // dropped onto the pad, spinning
  set_row(b, B::kW, {0.3, -0.2, 0.4});
  run(b, 1e-3, 2000, {0, 0, 0, 0});
  EXPECT_EQ(b.row(B::kP + 2)[0], 0.0);
  EXPECT_EQ(vec(b, B::kW).norm(), 0.0);
  // At rest its z axis is the pad's normal (tilted 3 deg), not world z; the yaw about the pad's normal is kept.
  const Eigen::Vector3d z = attitude(b).toRotationMatrix().col(2);
  EXPECT_NEAR((z - pad.toRotationMatrix().col(2)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(std::acos(z.z()), 3.0 * M_PI / 180.0, 1e-12);
  const Eigen::Quaterniond twist = pad.conjugate() * attitude(b);  // a rotation about z alone
  EXPECT_NEAR(std::hypot(twist.x(), twist.y()), 0.0, 1e-12);
  // Below hover thrust it stays on the pad at that attitude; above, it lifts off.
  const double wh = b.hover_rotor_speed();
  run(b, 1e-3, 500, {0.9 * wh, 0.9 * wh, 0.9 * wh, 0.9 * wh});
  EXPECT_EQ(b.row(B::kP + 2)[0], 0.0);
  EXPECT_NEAR((attitude(b).toRotationMatrix().col(2) - pad.toRotationMatrix().col(2)).norm(), 0.0, 1e-12);
  run(b, 1e-3, 1000, {1.2 * wh, 1.2 * wh, 1.2 * wh, 1.2 * wh});
  EXPECT_GT(b.row(B::kP + 2)[0], 0.05);
  // A level pad (the default) is what it was: body z along world z at rest.
  EXPECT_EQ(small_quad().ground_attitude, Eigen::Vector4d(1.0, 0.0, 0.0, 0.0));
}

TEST(QuadrotorBatch, BatchEqualsSingleVehiclesBitForBit) {
  const std::size_t n = 512 + 37;  // three blocks of 256 (so both threads work), not a multiple of any SIMD width
  QuadrotorParams p = small_quad();
  p.rotor_drag_xy = 1.0e-6;
  p.rotor_drag_z = 0.7e-6;
  p.body_drag = Eigen::Vector3d(0.002, 0.002, 0.004);
  B batch(p, n);
  std::vector<B> singles(n, B(p, 1));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> cmd(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int r = 0; r < B::kRows; ++r) {
      double x = u(rng);
      if (r == B::kP + 2) x = 1.0 + x;  // airborne
      if (r >= B::kRotor && r < B::kRotor + 4) x = 1800 + 200 * x;
      batch.row(r)[i] = x;
      singles[i].row(r)[0] = x;
    }
    for (int k = 0; k < 4; ++k) cmd[4 * i + k] = 1800 + 300 * u(rng);
  }
  for (int k = 0; k < 50; ++k) {
    batch.step(2e-3, cmd.data(), 2);
    for (std::size_t i = 0; i < n; ++i) singles[i].step(2e-3, &cmd[4 * i], 1);
  }
  for (std::size_t i = 0; i < n; ++i) {
    for (int r = 0; r < B::kRows; ++r) {
      ASSERT_EQ(std::memcmp(&batch.row(r)[i], &singles[i].row(r)[0], sizeof(double)), 0)
          << "vehicle " << i << " row " << r;
    }
  }
}

TEST(QuadrotorBatch, RejectsBadTimeStepAndNonFiniteCommands) {
  B b(small_quad(), 2);
  std::vector<double> cmd(8, 100.0);
  EXPECT_EQ(b.step(0.0, cmd.data()).status, StepStatus::kBadTimeStep);
  EXPECT_EQ(b.step(-1e-3, cmd.data()).status, StepStatus::kBadTimeStep);
  EXPECT_EQ(b.step(std::nan(""), cmd.data()).status, StepStatus::kBadTimeStep);
  cmd[6] = std::numeric_limits<double>::infinity();
  const StepResult r = b.step(1e-3, cmd.data());
  EXPECT_EQ(r.status, StepStatus::kNonFiniteCommand);
  EXPECT_EQ(r.index, 6);
  EXPECT_EQ(b.time(), 0.0);  // nothing advanced
}

TEST(QuadrotorBatch, RejectsNonFiniteStateZeroQuaternionAndTooLongSteps) {
  B b(small_quad(), 3);
  std::vector<double> cmd(12, 100.0);
  b.row(B::kV + 1)[2] = std::numeric_limits<double>::quiet_NaN();
  StepResult r = b.step(1e-3, cmd.data());
  EXPECT_EQ(r.status, StepStatus::kNonFiniteState);
  EXPECT_EQ(r.index, (B::kV + 1) * 3 + 2);
  b.row(B::kV + 1)[2] = 0.0;
  b.row(B::kForceExt)[0] = std::numeric_limits<double>::infinity();
  r = b.step(1e-3, cmd.data());
  EXPECT_EQ(r.status, StepStatus::kNonFiniteState);
  EXPECT_EQ(r.index, B::kForceExt * 3 + 0);
  b.row(B::kForceExt)[0] = 0.0;
  for (int k = 0; k < 4; ++k) b.row(B::kQ + k)[1] = 0.0;
  r = b.step(1e-3, cmd.data());
  EXPECT_EQ(r.status, StepStatus::kZeroQuaternion);
  EXPECT_EQ(r.index, 1);
  b.row(B::kQ)[1] = 1.0;
  const auto saved = B::max_substeps();
  B::set_max_substeps(10);
  EXPECT_EQ(b.step(0.0105, cmd.data()).status, StepStatus::kTooManySubsteps);  // 11 sub-steps of 1 ms
  EXPECT_EQ(b.step(0.010, cmd.data()).status, StepStatus::kOk);
  B::set_max_substeps(saved);
  EXPECT_DOUBLE_EQ(b.time(), 0.010);
}

TEST(QuadrotorBatch, AStepThatOverflowsReportsDivergenceNotSilentNaN) {
  B b(small_quad(), 2);
  std::vector<double> cmd(8, 100.0);
  b.row(B::kTorqueExt + 0)[1] = 1e300;  // finite, but w overflows within the step
  const StepResult r = b.step(1e-3, cmd.data());
  EXPECT_EQ(r.status, StepStatus::kDiverged);
  EXPECT_EQ(r.index % 2, 1);                    // vehicle 1
  EXPECT_TRUE(std::isfinite(b.row(B::kW)[0]));  // vehicle 0 is fine
}

TEST(QuadrotorBatch, ConcurrentStepsFromManyThreadsEqualTheSameStepsInSequence) {
  constexpr std::size_t n = 300;  // two blocks: the pool is used
  B shared(small_quad(), n), serial(small_quad(), n);
  for (std::size_t i = 0; i < n; ++i) {
    shared.row(B::kP + 2)[i] = serial.row(B::kP + 2)[i] = 1.0 + 0.01 * static_cast<double>(i);
  }
  std::vector<double> cmd(4 * n, 500.0);
  constexpr int kThreads = 4, kSteps = 25;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&] {
      for (int s = 0; s < kSteps; ++s) ASSERT_EQ(shared.step(1e-3, cmd.data(), 2).status, StepStatus::kOk);
    });
  }
  for (auto& t : threads) t.join();
  for (int s = 0; s < kThreads * kSteps; ++s) ASSERT_EQ(serial.step(1e-3, cmd.data(), 1).status, StepStatus::kOk);
  EXPECT_EQ(shared.time(), serial.time());
  for (int r = 0; r < B::kRows; ++r) {
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(std::memcmp(&shared.row(r)[i], &serial.row(r)[i], sizeof(double)), 0)
          << "row " << r << " vehicle " << i;
    }
  }
}

// step_batches: several batches (each its own step length, a fleet's vehicles) in one call equal each batch's own
// step bit for bit, on any thread count; a failing batch is named and the others are still stepped.
TEST(QuadrotorBatch, StepBatchesIsEachBatchsOwnStep) {
  const std::vector<std::size_t> sizes = {1, 3, 1, 2};
  const std::vector<double> dts = {1e-3, 2.5e-4, 7e-3, 1e-3};
  auto make = [&](std::vector<B>& out) {
    for (std::size_t k = 0; k < sizes.size(); ++k) {
      out.emplace_back(small_quad(), sizes[k]);
      for (std::size_t i = 0; i < sizes[k]; ++i) {
        set_row(out[k], B::kP, {0.1 * k, -0.2 * i, 5.0}, i);
        set_row(out[k], B::kW, {0.3 * i, 0.1 * k, -0.2}, i);
      }
    }
  };
  for (int nthreads : {1, 2, 0}) {
    std::vector<B> together, alone;
    together.reserve(sizes.size());
    alone.reserve(sizes.size());
    make(together);
    make(alone);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.8, 1.2);
    const double w = together[0].hover_rotor_speed();
    for (int s = 0; s < 30; ++s) {
      std::vector<std::vector<double>> cmds(sizes.size());
      std::vector<BatchStep> steps;
      for (std::size_t k = 0; k < sizes.size(); ++k) {
        for (std::size_t j = 0; j < 4 * sizes[k]; ++j) cmds[k].push_back(w * u(rng));
        steps.push_back({&together[k], dts[k], cmds[k].data()});
      }
      ASSERT_EQ(step_batches(steps.data(), steps.size(), nthreads).status, StepStatus::kOk);
      for (std::size_t k = 0; k < sizes.size(); ++k) {
        ASSERT_EQ(alone[k].step(dts[k], cmds[k].data(), 1).status, StepStatus::kOk);
      }
    }
    for (std::size_t k = 0; k < sizes.size(); ++k) {
      EXPECT_EQ(together[k].time(), alone[k].time());
      for (int r = 0; r < B::kRows; ++r) {
        for (std::size_t i = 0; i < sizes[k]; ++i) {
          ASSERT_EQ(std::memcmp(&together[k].row(r)[i], &alone[k].row(r)[i], sizeof(double)), 0)
              << "threads " << nthreads << " batch " << k << " row " << r << " vehicle " << i;
        }
      }
    }
  }
  B a(small_quad(), 1), b(small_quad(), 1);
  set_row(a, B::kP, {0.0, 0.0, 5.0});
  set_row(b, B::kP, {0.0, 0.0, 5.0});
  const std::vector<double> good(4, a.hover_rotor_speed());
  std::vector<double> bad = good;
  bad[2] = std::nan("");
  const BatchStep steps[] = {{&a, 1e-3, good.data()}, {&b, 1e-3, bad.data()}};
  std::size_t failed = 99;
  const StepResult r = step_batches(steps, 2, 1, &failed);
  EXPECT_EQ(r.status, StepStatus::kNonFiniteCommand);
  EXPECT_EQ(r.index, 2);
  EXPECT_EQ(failed, 1u);
  EXPECT_EQ(a.time(), 1e-3);  // the good one stepped
  EXPECT_EQ(b.time(), 0.0);
}

}  // namespace
}  // namespace cufund
