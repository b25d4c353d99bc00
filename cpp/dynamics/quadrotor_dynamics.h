// The quadrotor's equations of motion (paper eqs. 2-5 with motor lag and drag) and one RK4
// sub-step, written per vehicle on plain doubles so that the batch loop vectorises across vehicles.
#pragma once

#include <algorithm>
#include <cmath>

#include "ground_effect.h"
#include "quadrotor_params.h"

#if defined(__GNUC__)
#define CUFUND_INLINE inline __attribute__((always_inline))
#else
#define CUFUND_INLINE inline
#endif

// Fixed-length loops are unrolled completely so that their arrays become registers and the
// per-vehicle loop can vectorise across vehicles.
#if defined(__GNUC__) && !defined(__clang__)
#define CUFUND_UNROLL _Pragma("GCC unroll 32")
#else
#define CUFUND_UNROLL
#endif

namespace cufund {

// Parameters folded into the numbers the right-hand side uses.
struct DynamicsConstants {
  double inv_mass, gravity;
  double J[9], J_inv[9];  // row-major, body FLU
  double k_f, inv_tau_m;
  double omega_min, omega_max;
  double r[kNumRotors][3];        // rotor positions, body FLU
  double yaw_moment[kNumRotors];  // -s_i * c_m: M_z contribution per newton of rotor thrust
  double kd_xy, kd_z;             // rotor drag
  double cd[3];                   // body drag
  double ground_q[4];             // attitude at rest on the ground [w, x, y, z], yaw kept (a tilted pad)
  GroundEffectParams ge;          // used only by the kGroundEffect instantiation
};

DynamicsConstants make_constants(const QuadrotorParams& params);

// 17 states: p_W(3) v_W(3) q_WB(4) w_B(3) rotor speeds(4).
constexpr int kStateSize = 17;

// Inputs held constant over a step.
struct StepInputs {
  double omega_cmd[kNumRotors];  // already clipped to the rotor-speed limits
  double wind_W[3];
  double force_W[3];
  double torque_B[3];
  double eta[kNumRotors];          // rotor efficiency: scales each rotor's thrust and drag torque, in [0, 1]
  double floor_z;                  // ground/floor height below the vehicle [m] (-inf: none), kGroundEffect only
  double ceiling_z;                // ceiling height above the vehicle [m] (+inf: none), kGroundEffect only
  double thrust_gain[kNumRotors];  // ground x ceiling gain per rotor, from the sub-step's start (kGroundEffect only)
};

// The ground and ceiling gains of each rotor at state x (its hub's height over floor_z and under ceiling_z),
// held over an RK4 sub-step (evaluating them at every stage cost 4x for a change of O(h) in the gain).
CUFUND_INLINE void ground_effect_gains(const DynamicsConstants& c, const double* x, StepInputs& u) {
  const double qw = x[6], qx = x[7], qy = x[8], qz = x[9];
  const double s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz);
  const double R20 = s * (qx * qz - qw * qy), R21 = s * (qy * qz + qw * qx), R22 = 1.0 - s * (qx * qx + qy * qy);
  CUFUND_UNROLL
  for (int i = 0; i < kNumRotors; ++i) {
    const double z_hub = x[2] + R20 * c.r[i][0] + R21 * c.r[i][1] + R22 * (c.r[i][2] + c.ge.rotor_plane_height);
    u.thrust_gain[i] = ground_gain(c.ge, z_hub - u.floor_z) * ceiling_gain(c.ge, u.ceiling_z - z_hub);
  }
}

// kGround: a rigid ground plane at z = 0 (a template parameter so the vehicle loop has no branch on it).
// kGroundEffect: thrust scaled by the ground and ceiling gains at each rotor hub's height (ground_effect.h).
template <bool kGround, bool kGroundEffect>
CUFUND_INLINE void derivative(const DynamicsConstants& c, const double* x, const StepInputs& u, double* dx) {
  const double* p = x;
  const double* v = x + 3;
  const double* q = x + 6;
  const double* w = x + 10;
  const double* om = x + 13;
  (void)p;

  // R_WB of the normalised quaternion (RK4 stages are off the unit sphere by O(h^2)).
  const double qw = q[0], qx = q[1], qy = q[2], qz = q[3];
  const double s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz);
  const double R00 = 1.0 - s * (qy * qy + qz * qz), R01 = s * (qx * qy - qw * qz), R02 = s * (qx * qz + qw * qy);
  const double R10 = s * (qx * qy + qw * qz), R11 = 1.0 - s * (qx * qx + qz * qz), R12 = s * (qy * qz - qw * qx);
  const double R20 = s * (qx * qz - qw * qy), R21 = s * (qy * qz + qw * qx), R22 = 1.0 - s * (qx * qx + qy * qy);

  // Air-relative velocity in the body frame.
  const double aW0 = v[0] - u.wind_W[0], aW1 = v[1] - u.wind_W[1], aW2 = v[2] - u.wind_W[2];
  const double aB0 = R00 * aW0 + R10 * aW1 + R20 * aW2;
  const double aB1 = R01 * aW0 + R11 * aW1 + R21 * aW2;
  const double aB2 = R02 * aW0 + R12 * aW1 + R22 * aW2;

  // Body drag, quadratic.
  const double speed = std::sqrt(aB0 * aB0 + aB1 * aB1 + aB2 * aB2);
  double F0 = -speed * c.cd[0] * aB0;
  double F1 = -speed * c.cd[1] * aB1;
  double F2 = -speed * c.cd[2] * aB2;
  double M0 = 0.0, M1 = 0.0, M2 = 0.0;

  CUFUND_UNROLL

  for (int i = 0; i < kNumRotors; ++i) {
    const double rx = c.r[i][0], ry = c.r[i][1], rz = c.r[i][2];
    const double f_rotor = c.k_f * om[i] * om[i] * u.eta[i];  // what the rotor's drag torque follows
    double f = f_rotor;
    if constexpr (kGroundEffect) f *= u.thrust_gain[i];
    // Rotor hub air velocity: body air velocity plus w x r_i.
    const double l0 = aB0 + (w[1] * rz - w[2] * ry);
    const double l1 = aB1 + (w[2] * rx - w[0] * rz);
    const double l2 = aB2 + (w[0] * ry - w[1] * rx);
    // Rotor force: thrust along +z_B and rotor drag (H-force), applied at the hub.
    const double h0 = -om[i] * c.kd_xy * l0;
    const double h1 = -om[i] * c.kd_xy * l1;
    const double h2 = f - om[i] * c.kd_z * l2;
    F0 += h0;
    F1 += h1;
    F2 += h2;
    M0 += ry * h2 - rz * h1;
    M1 += rz * h0 - rx * h2;
    M2 += rx * h1 - ry * h0 + c.yaw_moment[i] * f_rotor;
  }
  M0 += u.torque_B[0];
  M1 += u.torque_B[1];
  M2 += u.torque_B[2];

  dx[0] = v[0];
  dx[1] = v[1];
  dx[2] = v[2];
  dx[3] = (R00 * F0 + R01 * F1 + R02 * F2 + u.force_W[0]) * c.inv_mass;
  dx[4] = (R10 * F0 + R11 * F1 + R12 * F2 + u.force_W[1]) * c.inv_mass;
  double az = (R20 * F0 + R21 * F1 + R22 * F2 + u.force_W[2]) * c.inv_mass - c.gravity;
  // Ground reaction: at or below z = 0 the ground cancels any net downward force.
  if constexpr (kGround) {
    dx[5] = x[2] <= 0.0 ? std::max(az, 0.0) : az;
  } else {
    dx[5] = az;
  }

  // q_dot = 1/2 q (x) (0, w_B)
  dx[6] = -0.5 * (qx * w[0] + qy * w[1] + qz * w[2]);
  dx[7] = 0.5 * (qw * w[0] + qy * w[2] - qz * w[1]);
  dx[8] = 0.5 * (qw * w[1] - qx * w[2] + qz * w[0]);
  dx[9] = 0.5 * (qw * w[2] + qx * w[1] - qy * w[0]);

  // J w_dot = M - w x J w
  const double* J = c.J;
  const double Jw0 = J[0] * w[0] + J[1] * w[1] + J[2] * w[2];
  const double Jw1 = J[3] * w[0] + J[4] * w[1] + J[5] * w[2];
  const double Jw2 = J[6] * w[0] + J[7] * w[1] + J[8] * w[2];
  const double t0 = M0 - (w[1] * Jw2 - w[2] * Jw1);
  const double t1 = M1 - (w[2] * Jw0 - w[0] * Jw2);
  const double t2 = M2 - (w[0] * Jw1 - w[1] * Jw0);
  const double* Ji = c.J_inv;
  dx[10] = Ji[0] * t0 + Ji[1] * t1 + Ji[2] * t2;
  dx[11] = Ji[3] * t0 + Ji[4] * t1 + Ji[5] * t2;
  dx[12] = Ji[6] * t0 + Ji[7] * t1 + Ji[8] * t2;

  CUFUND_UNROLL

  for (int i = 0; i < kNumRotors; ++i) dx[13 + i] = (u.omega_cmd[i] - om[i]) * c.inv_tau_m;
}

// On the ground and not climbing: the ground holds the vehicle (see rk4_substep).
CUFUND_INLINE bool resting_on_ground(const double* x) { return std::max(x[2], x[5]) <= 0.0; }

// One classical RK4 step of length h, then quaternion renormalisation and ground contact.
template <bool kGround, bool kGroundEffect>
CUFUND_INLINE void rk4_substep(const DynamicsConstants& c, const StepInputs& u, double h, double* x) {
  double k1[kStateSize], k2[kStateSize], k3[kStateSize], k4[kStateSize], y[kStateSize];
  derivative<kGround, kGroundEffect>(c, x, u, k1);
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) y[j] = x[j] + 0.5 * h * k1[j];
  derivative<kGround, kGroundEffect>(c, y, u, k2);
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) y[j] = x[j] + 0.5 * h * k2[j];
  derivative<kGround, kGroundEffect>(c, y, u, k3);
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) y[j] = x[j] + h * k3[j];
  derivative<kGround, kGroundEffect>(c, y, u, k4);
  const double h6 = h / 6.0;
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) x[j] += h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]);

  const double qn = 1.0 / std::sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9]);
  CUFUND_UNROLL
  for (int j = 6; j < 10; ++j) x[j] *= qn;

  if constexpr (kGround) {
    // Never below the ground; a vehicle that touches it and is not climbing rests there:
    // static friction holds it, the landing gear levels it (yaw kept), rotation stops.
    // Branch-free (one comparison per select), so the loop over vehicles stays vectorised.
    x[2] = std::max(x[2], 0.0);
    // On a tilted pad it rests at the pad's attitude g with its yaw kept: q = g (x) twist_z(g^-1 (x) q)
    // (g = identity, level ground: exactly the yaw twist of q).
    const bool resting = resting_on_ground(x);
    const double gw = c.ground_q[0], gx = c.ground_q[1], gy = c.ground_q[2], gz = c.ground_q[3];
    const double rw = gw * x[6] + gx * x[7] + gy * x[8] + gz * x[9];  // g^-1 (x) q: its w and z
    const double rz = gw * x[9] - gx * x[8] + gy * x[7] - gz * x[6];
    const double twist = rw * rw + rz * rz;
    const bool has_twist = twist > 1e-24;
    const double tn = has_twist ? 1.0 / std::sqrt(twist) : 0.0;
    const double tw = has_twist ? rw * tn : 1.0;
    const double tz = rz * tn;
    x[3] = resting ? 0.0 : x[3];
    x[4] = resting ? 0.0 : x[4];
    x[5] = resting ? 0.0 : x[5];
    x[6] = resting ? gw * tw - gz * tz : x[6];
    x[7] = resting ? gx * tw + gy * tz : x[7];
    x[8] = resting ? gy * tw - gx * tz : x[8];
    x[9] = resting ? gz * tw + gw * tz : x[9];
    x[10] = resting ? 0.0 : x[10];
    x[11] = resting ? 0.0 : x[11];
    x[12] = resting ? 0.0 : x[12];
  }
}

}  // namespace cufund
