// EnvBatch against itself and by hand: env i of a batch equals a batch of one seeded seed + i bit for bit (through
// autoresets), a vehicle at rest at the hover point earns `alive`, and the step after a terminal resets the env.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "env_batch.h"

namespace cufund {
namespace {

QuadrotorParams crazyflie() {
  QuadrotorParams p;
  p.mass = 0.03;
  p.inertia = Eigen::Vector3d(1.43e-5, 1.43e-5, 2.89e-5).asDiagonal();
  p.arm_length = 0.043;
  p.k_f = 2.3e-08;
  p.c_m = 7.8e-10 / 2.3e-08;
  p.tau_m = 0.072;
  p.rotor_speed_max = 2500.0;
  p.max_integration_step = 0.01;
  return p;
}

EnvTaskParams hover_task(ActionMode mode) {
  EnvTaskParams t;
  t.action_mode = mode;
  t.targets = {0.0, 0.0, 1.0, 0.0};
  t.max_steps = 40;
  return t;
}

TEST(EnvBatch, EnvIEqualsABatchOfOneSeededSeedPlusI) {
  for (ActionMode mode : {ActionMode::kRotorSpeeds, ActionMode::kThrustRates, ActionMode::kVelocity}) {
    const std::size_t n = 3;
    const EnvTaskParams task = hover_task(mode);
    EnvBatch all(crazyflie(), task, n);
    std::vector<EnvBatch> one;
    for (std::size_t i = 0; i < n; ++i) one.emplace_back(crazyflie(), task, 1);
    const int D = all.obs_size();
    std::vector<float> obs(n * D), o1(D);
    all.reset(100, obs.data());
    for (std::size_t i = 0; i < n; ++i) {
      one[i].reset(100 + i, o1.data());
      for (int k = 0; k < D; ++k) ASSERT_EQ(obs[i * D + k], o1[k]);
    }
    std::vector<double> a(4 * n), r(n);
    bool te[3], tr[3];
    for (int step = 0; step < 120; ++step) {
      for (std::size_t k = 0; k < 4 * n; ++k) a[k] = 0.5 * std::sin(0.1 * step + static_cast<double>(k));
      all.step(a.data(), obs.data(), r.data(), te, tr);
      for (std::size_t i = 0; i < n; ++i) {
        double r1;
        bool te1, tr1;
        one[i].step(&a[4 * i], o1.data(), &r1, &te1, &tr1);
        ASSERT_EQ(r[i], r1) << step;
        ASSERT_EQ(te[i], te1);
        ASSERT_EQ(tr[i], tr1);
        for (int k = 0; k < D; ++k) ASSERT_EQ(obs[i * D + k], o1[k]);
      }
    }
  }
}

TEST(EnvBatch, AtRestAtTheHoverPointEarnsAliveThenAutoresets) {
  EnvBatch e(crazyflie(), hover_task(ActionMode::kRotorSpeeds), 1);
  std::vector<float> obs(e.obs_size());
  e.reset(0, obs.data());
  QuadrotorBatch& b = e.batch();
  const double pos[3] = {0.0, 0.0, 1.0};
  for (int k = 0; k < 3; ++k) {
    b.row(QuadrotorBatch::kP + k)[0] = pos[k];
    b.row(QuadrotorBatch::kV + k)[0] = 0.0;
    b.row(QuadrotorBatch::kW + k)[0] = 0.0;
  }
  b.row(QuadrotorBatch::kQ)[0] = 1.0;
  for (int k = 1; k < 4; ++k) b.row(QuadrotorBatch::kQ + k)[0] = 0.0;
  for (int k = 0; k < 4; ++k) b.row(QuadrotorBatch::kRotor + k)[0] = b.hover_rotor_speed();
  const double zero[4] = {0, 0, 0, 0};
  double r;
  bool te, tr;
  e.step(zero, obs.data(), &r, &te, &tr);
  EXPECT_FALSE(te);
  EXPECT_NEAR(r, 1.0, 1e-4);                // alive, less a micrometre of drift
  b.row(QuadrotorBatch::kP + 2)[0] = -3.0;  // below the ground and out of bounds: a crash
  e.step(zero, obs.data(), &r, &te, &tr);
  EXPECT_TRUE(te);
  EXPECT_LT(r, -9.0);
  const double full[4] = {1, 1, 1, 1};  // ignored: this step resets
  e.step(full, obs.data(), &r, &te, &tr);
  EXPECT_EQ(r, 0.0);
  EXPECT_FALSE(te);
  EXPECT_FALSE(tr);
  EXPECT_EQ(e.episode_steps()[0], 0);
  for (int k = e.obs_size() - 4; k < e.obs_size(); ++k) EXPECT_EQ(obs[k], 0.0f);
}

}  // namespace
}  // namespace cufund
