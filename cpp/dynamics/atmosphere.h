// The wind a vehicle flies in (docs/guides/atmosphere.md): a mean wind from the 20 ft wind speed with a shear
// profile, an optional wind grid added to it, Dryden turbulence (MIL-F-8785C / MIL-HDBK-1797 low-altitude forms)
// sampled along the vehicle's path, and 1-cosine gusts. Evaluated for every vehicle once per update_period of
// simulated time and held over the steps in between (QuadrotorBatch::step writes it into the wind rows).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cufund {

enum class WindShear : int { kNone = 0, kLog = 1, kPower = 2 };

struct GustEvent {
  double t_start = 0.0;    // [s]
  double duration = 1.0;   // [s] > 0
  double amplitude = 0.0;  // peak speed [m/s]
  double direction = 0.0;  // the direction it blows towards, counter-clockwise from +x [rad]
};

struct AtmosphereParams {
  double wind_20ft = 0.0;   // mean wind speed at 20 ft (6.096 m) [m/s] >= 0
  double direction = 0.0;   // the direction the mean wind blows towards, counter-clockwise from +x [rad]
  bool turbulence = false;  // Dryden turbulence on the mean wind
  WindShear shear = WindShear::kNone;
  double roughness_z0 = 0.0457;       // log law's roughness length [m] (MIL-F-8785C: 0.15 ft)
  double shear_exponent = 1.0 / 7.0;  // power law's exponent
  double min_airspeed = 1.0;          // floor of the airspeed that converts the spatial spectrum to time [m/s] > 0
  double update_period = 0.005;       // [s] > 0
  std::uint64_t seed = 0;
  std::vector<GustEvent> gusts;
  // Wind grid (empty: none): strictly increasing axes, data (nx, ny, nz, 3) row-major [m/s]; clamped outside.
  std::vector<double> grid_x, grid_y, grid_z, grid_wind;
};

// "" when the parameters are usable, else a message naming the field.
std::string validate(const AtmosphereParams& a);

// Dryden scales at height h [m] for a 20 ft wind speed w20 [m/s] (h clamped to [10, 1000] ft): sigma_u, sigma_v,
// sigma_w [m/s] and L_u, L_v, L_w [m].
struct DrydenScales {
  double sigma_u, sigma_v, sigma_w, L_u, L_v, L_w;
};
DrydenScales dryden_scales(double h, double w20);

// Mean wind speed at height h [m] under the shear profile (log: w20 ln(h/z0) / ln(20 ft/z0), 0 below z0;
// power: w20 (h / 20 ft)^alpha, 0 below ground; none: w20).
double mean_wind_speed(const AtmosphereParams& a, double h);

// The 1-cosine gust's speed at time t [s] (0 outside [t_start, t_start + duration]).
double gust_speed(const GustEvent& g, double t);

// The grid's wind at p (trilinear, clamped to the grid's box); zero without a grid.
void grid_wind(const AtmosphereParams& a, const double* p, double* out);

class Atmosphere {
 public:
  Atmosphere() = default;
  Atmosphere(const AtmosphereParams& params, std::size_t n);

  bool enabled() const { return enabled_; }
  const AtmosphereParams& params() const { return params_; }
  // Back to the seeded start: filter states zero, random streams restarted, the next update at t = 0.
  void reset();
  // When t has reached the next update time: writes each vehicle's wind (3 rows of wind_rows, SoA with stride n)
  // from its position and velocity rows.
  void update(double t, const double* p_rows, const double* v_rows, double* wind_rows, std::size_t n);

 private:
  struct Rng {
    std::uint64_t s[4];
    double spare;
    bool has_spare;
  };
  double normal(Rng& r);

  bool enabled_ = false;
  AtmosphereParams params_;
  std::size_t n_ = 0;
  double next_update_ = 0.0;
  double last_update_ = 0.0;
  std::vector<Rng> rng_;
  std::vector<double> filter_;  // per vehicle: u, v1, v2, w1, w2 (unit-variance normalised)
};

}  // namespace cufund
