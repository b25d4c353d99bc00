// Ground and ceiling effect on rotor thrust (docs/guides/atmosphere.md).
//
// Ground: Cheeseman & Bennett (1955) T_IGE/T_OGE = 1 / (1 - (R / 4z)^2) for one rotor at height z above the
// ground, with the multirotor terms of Sanchez-Cuevas, Heredia & Ollero (2017), "Characterization of the
// aerodynamic ground effect and its influence in multirotor control", Int. J. Aerospace Eng. 2017:1823056:
//   T_IGE/T_OGE = 1 / (1 - (R/4z)^2 - R^2 z / (d^2 + 4z^2)^(3/2) - (R^2/2) z / (2d^2 + 4z^2)^(3/2)
//                        - 2 R^2 z K_b / (b^2 + 4z^2)^(3/2))
// (d: distance between adjacent rotors, b: rotor to body centre, K_b: the body's empirical coefficient).
// Ceiling: Sanchez-Cuevas, Heredia & Ollero (2017), "Multirotor UAS for bridge inspection by contact using the
// ceiling effect", ICUAS 2017: T_ICE/T_OCE = 1 / (1 - (1/K1) (R / (z + K2))^2), z the distance to the ceiling.
// Heights are clamped to [min_height, kMaxHeight]; the gains multiply (ground x ceiling) and apply per rotor at
// the rotor hub's own height.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

namespace cufund {

struct GroundEffectParams {
  bool enabled = false;             // off: thrust unchanged (the integrator takes the branch-free path without it)
  double rotor_radius = 0.0;        // R [m] > 0
  double rotor_spacing = 0.0;       // d: distance between adjacent rotor centres [m] > 0 (1e6: one rotor alone)
  double body_distance = 0.0;       // b: rotor centre to body centre [m] >= 0
  double k_body = 0.0;              // K_b, the body term's coefficient (Sanchez-Cuevas et al.: 2) >= 0
  double ceiling_k1 = 6.924;        // K1 > 0 (0 or inf: no ceiling term)
  double ceiling_k2 = 0.0;          // K2 [m] >= 0
  double rotor_plane_height = 0.0;  // rotor hubs above the body origin along body z [m] (landing gear) >= 0
  double min_height = 0.0;          // clamp [m] > 0: heights below it count as it
};

// Heights above this [m] count as this (no floor or ceiling: gain 1 within (R / 4e6)^2).
constexpr double kGroundEffectMaxHeight = 1e6;

// T_IGE / T_OGE at rotor height z above the ground [m] (clamped).
inline double ground_gain(const GroundEffectParams& g, double z) {
  z = std::min(std::max(z, g.min_height), kGroundEffectMaxHeight);
  const double R2 = g.rotor_radius * g.rotor_radius;
  const double z4 = 4.0 * z * z;
  const double d2 = g.rotor_spacing * g.rotor_spacing;
  const double b2 = g.body_distance * g.body_distance;
  const double s1 = d2 + z4, s2 = 2.0 * d2 + z4, s3 = b2 + z4;
  const double single = R2 / (4.0 * z4);  // (R / 4z)^2
  const double rotors = R2 * z / (s1 * std::sqrt(s1)) + 0.5 * R2 * z / (s2 * std::sqrt(s2));
  const double body = 2.0 * R2 * z * g.k_body / (s3 * std::sqrt(s3));
  return 1.0 / (1.0 - single - rotors - body);
}

// T_ICE / T_OCE at distance z below the ceiling [m] (clamped).
inline double ceiling_gain(const GroundEffectParams& g, double z) {
  z = std::min(std::max(z, g.min_height), kGroundEffectMaxHeight);
  const double r = g.rotor_radius / (z + g.ceiling_k2);
  return 1.0 / (1.0 - r * r / g.ceiling_k1);
}

// "" when the parameters give a finite gain >= 1 at every height, else a message naming the field.
std::string validate(const GroundEffectParams& g);

}  // namespace cufund
