#include "ground_effect.h"

#include <sstream>

namespace cufund {

std::string validate(const GroundEffectParams& g) {
  std::ostringstream os;
  auto finite_at_least = [&](const char* name, double v, double lo, bool strict) {
    if (!(std::isfinite(v) && (strict ? v > lo : v >= lo))) {
      os << "ground_effect." << name << " must be a finite number " << (strict ? "> " : ">= ") << lo << ", got " << v;
      return false;
    }
    return true;
  };
  if (!finite_at_least("rotor_radius", g.rotor_radius, 0.0, true)) return os.str();
  if (!finite_at_least("rotor_spacing", g.rotor_spacing, 0.0, true)) return os.str();
  if (!finite_at_least("body_distance", g.body_distance, 0.0, false)) return os.str();
  if (!finite_at_least("k_body", g.k_body, 0.0, false)) return os.str();
  if (!finite_at_least("ceiling_k2", g.ceiling_k2, 0.0, false)) return os.str();
  if (!finite_at_least("min_height", g.min_height, 0.0, true)) return os.str();
  if (!finite_at_least("rotor_plane_height", g.rotor_plane_height, 0.0, false)) return os.str();
  if (!(g.ceiling_k1 > 0.0)) {  // +inf: no ceiling term
    os << "ground_effect.ceiling_k1 must be a number > 0 (inf: no ceiling effect), got " << g.ceiling_k1;
    return os.str();
  }
  // The gains must stay finite and >= 1 at every height from min_height up (the ground gain's rotor terms peak
  // above min_height): sampled on a log grid.
  for (int k = 0; k <= 400; ++k) {
    const double z = g.min_height * std::pow(kGroundEffectMaxHeight / g.min_height, k / 400.0);
    const double gg = ground_gain(g, z), gc = ceiling_gain(g, z);
    if (!(std::isfinite(gg) && gg >= 1.0 && gg <= 10.0)) {
      os << "ground_effect: the ground gain is " << gg << " at " << z
         << " m (outside [1, 10]: the model is past its singularity); raise ground_effect.min_height (now "
         << g.min_height << " m) or lower k_body";
      return os.str();
    }
    if (!(std::isfinite(gc) && gc >= 1.0 && gc <= 10.0)) {
      os << "ground_effect: the ceiling gain is " << gc << " at " << z
         << " m (outside [1, 10]: the model is past its singularity); raise ground_effect.min_height (now "
         << g.min_height << " m), ceiling_k1 or ceiling_k2";
      return os.str();
    }
  }
  return "";
}

}  // namespace cufund
