#include "atmosphere.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace cufund {

namespace {

constexpr double kFoot = 0.3048;       // [m]
constexpr double kH20 = 20.0 * kFoot;  // 6.096 m
constexpr double kPi = 3.14159265358979323846;

std::uint64_t splitmix64(std::uint64_t& x) {
  std::uint64_t z = (x += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

bool increasing_axis(const std::vector<double>& a) {
  if (a.size() < 2) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a[i]) || (i > 0 && !(a[i] > a[i - 1]))) return false;
  }
  return true;
}

// Index k and fraction f of x on the axis (clamped to its ends).
void locate(const std::vector<double>& a, double x, std::size_t& k, double& f) {
  const std::size_t n = a.size();
  if (!(x > a[0])) {
    k = 0;
    f = 0.0;
    return;
  }
  if (!(x < a[n - 1])) {
    k = n - 2;
    f = 1.0;
    return;
  }
  k = static_cast<std::size_t>(std::upper_bound(a.begin(), a.end(), x) - a.begin()) - 1;
  f = (x - a[k]) / (a[k + 1] - a[k]);
}

}  // namespace

std::string validate(const AtmosphereParams& a) {
  std::ostringstream os;
  auto bad = [&](const char* name, double v, const char* what) {
    os << "atmosphere." << name << " must be " << what << ", got " << v;
    return os.str();
  };
  if (!(std::isfinite(a.wind_20ft) && a.wind_20ft >= 0.0 && a.wind_20ft <= 100.0))
    return bad("wind_20ft_mps", a.wind_20ft, "a finite speed in [0, 100] [m/s]");
  if (!std::isfinite(a.direction)) return bad("direction_deg", a.direction, "finite");
  if (!(std::isfinite(a.roughness_z0) && a.roughness_z0 > 0.0 && a.roughness_z0 < kH20))
    return bad("shear.z0_m", a.roughness_z0, "a finite length in (0, 6.096) [m]");
  if (!(std::isfinite(a.shear_exponent) && a.shear_exponent >= 0.0 && a.shear_exponent <= 1.0))
    return bad("shear.exponent", a.shear_exponent, "in [0, 1]");
  if (!(std::isfinite(a.min_airspeed) && a.min_airspeed > 0.0))
    return bad("min_airspeed_mps", a.min_airspeed, "a finite speed > 0 [m/s]");
  if (!(std::isfinite(a.update_period) && a.update_period > 0.0 && a.update_period <= 1.0))
    return bad("update_hz", 1.0 / a.update_period, "a rate >= 1 [Hz]");
  for (std::size_t i = 0; i < a.gusts.size(); ++i) {
    const GustEvent& g = a.gusts[i];
    if (!(std::isfinite(g.t_start) && std::isfinite(g.amplitude) && std::isfinite(g.direction) &&
          std::isfinite(g.duration) && g.duration > 0.0 && std::abs(g.amplitude) <= 100.0)) {
      os << "atmosphere.gusts[" << i
         << "] must have finite t_start [s], duration > 0 [s], |amplitude_mps| <= 100 and direction_deg";
      return os.str();
    }
  }
  const bool any_grid = !(a.grid_x.empty() && a.grid_y.empty() && a.grid_z.empty() && a.grid_wind.empty());
  if (any_grid) {
    if (!increasing_axis(a.grid_x) || !increasing_axis(a.grid_y) || !increasing_axis(a.grid_z)) {
      return "atmosphere.grid_file: the axes x, y, z must each hold >= 2 finite, strictly increasing values [m]";
    }
    const std::size_t want = a.grid_x.size() * a.grid_y.size() * a.grid_z.size() * 3;
    if (a.grid_wind.size() != want) {
      os << "atmosphere.grid_file: wind must hold nx * ny * nz * 3 = " << want << " values, got " << a.grid_wind.size();
      return os.str();
    }
    for (double w : a.grid_wind) {
      if (!(std::isfinite(w) && std::abs(w) <= 200.0)) return bad("grid_file: wind", w, "finite and within +-200 m/s");
    }
  }
  return "";
}

DrydenScales dryden_scales(double h, double w20) {
  const double h_ft = std::min(std::max(h / kFoot, 10.0), 1000.0);
  const double s = 0.177 + 0.000823 * h_ft;
  DrydenScales d{};
  d.sigma_w = 0.1 * w20;
  d.sigma_u = d.sigma_w / std::pow(s, 0.4);
  d.sigma_v = d.sigma_u;
  d.L_w = h_ft * kFoot;
  d.L_u = h_ft / std::pow(s, 1.2) * kFoot;
  d.L_v = d.L_u;
  return d;
}

double mean_wind_speed(const AtmosphereParams& a, double h) {
  switch (a.shear) {
    case WindShear::kNone: return a.wind_20ft;
    case WindShear::kLog:
      if (!(h > a.roughness_z0)) return 0.0;
      return a.wind_20ft * std::log(h / a.roughness_z0) / std::log(kH20 / a.roughness_z0);
    case WindShear::kPower:
      if (!(h > 0.0)) return 0.0;
      return a.wind_20ft * std::pow(h / kH20, a.shear_exponent);
  }
  return a.wind_20ft;
}

double gust_speed(const GustEvent& g, double t) {
  const double s = t - g.t_start;
  if (!(s >= 0.0 && s <= g.duration)) return 0.0;
  return 0.5 * g.amplitude * (1.0 - std::cos(2.0 * kPi * s / g.duration));
}

void grid_wind(const AtmosphereParams& a, const double* p, double* out) {
  out[0] = out[1] = out[2] = 0.0;
  if (a.grid_wind.empty()) return;
  std::size_t i, j, k;
  double fx, fy, fz;
  locate(a.grid_x, p[0], i, fx);
  locate(a.grid_y, p[1], j, fy);
  locate(a.grid_z, p[2], k, fz);
  const std::size_t ny = a.grid_y.size(), nz = a.grid_z.size();
  for (int di = 0; di < 2; ++di) {
    const double wx = di ? fx : 1.0 - fx;
    for (int dj = 0; dj < 2; ++dj) {
      const double wy = dj ? fy : 1.0 - fy;
      for (int dk = 0; dk < 2; ++dk) {
        const double w = wx * wy * (dk ? fz : 1.0 - fz);
        const double* c = &a.grid_wind[(((i + di) * ny + (j + dj)) * nz + (k + dk)) * 3];
        out[0] += w * c[0];
        out[1] += w * c[1];
        out[2] += w * c[2];
      }
    }
  }
}

Atmosphere::Atmosphere(const AtmosphereParams& params, std::size_t n) : enabled_(true), params_(params), n_(n) {
  reset();
}

double Atmosphere::normal(Rng& r) {
  if (r.has_spare) {
    r.has_spare = false;
    return r.spare;
  }
  double u, v, s;
  do {  // Marsaglia's polar method on xoshiro256** (portable: the same draws on every platform)
    auto next = [&r] {
      const std::uint64_t result = rotl(r.s[1] * 5, 7) * 9;
      const std::uint64_t t = r.s[1] << 17;
      r.s[2] ^= r.s[0];
      r.s[3] ^= r.s[1];
      r.s[1] ^= r.s[2];
      r.s[0] ^= r.s[3];
      r.s[2] ^= t;
      r.s[3] = rotl(r.s[3], 45);
      return static_cast<double>(result >> 11) * 0x1.0p-53;
    };
    u = 2.0 * next() - 1.0;
    v = 2.0 * next() - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double m = std::sqrt(-2.0 * std::log(s) / s);
  r.spare = v * m;
  r.has_spare = true;
  return u * m;
}

void Atmosphere::reset() {
  if (!enabled_) return;
  next_update_ = -1e300;
  rng_.assign(n_, Rng{});
  filter_.assign(5 * n_, 0.0);
  for (std::size_t i = 0; i < n_; ++i) {
    std::uint64_t x = params_.seed ^ (0x632be59bd9b4e019ULL * (i + 1));
    for (auto& w : rng_[i].s) w = splitmix64(x);
    rng_[i].has_spare = false;
    // Start from the filters' stationary distribution: u ~ N(0, 1), each 2-state pair ~ N(0, I/4).
    double* f = &filter_[5 * i];
    f[0] = normal(rng_[i]);
    for (int k = 1; k < 5; ++k) f[k] = 0.5 * normal(rng_[i]);
  }
  last_update_ = 0.0;
}

void Atmosphere::update(double t, const double* p_rows, const double* v_rows, double* wind_rows, std::size_t n) {
  if (!enabled_ || n != n_ || t < next_update_ - 1e-9) return;
  const double dt = next_update_ < -1e299 ? 0.0 : t - last_update_;
  last_update_ = t;
  next_update_ = t + params_.update_period;
  const AtmosphereParams& a = params_;
  const double c = std::cos(a.direction), s = std::sin(a.direction);
  const bool turbulent = a.turbulence && a.wind_20ft > 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double p[3] = {p_rows[i], p_rows[n + i], p_rows[2 * n + i]};
    const double U = mean_wind_speed(a, p[2]);
    double w[3];
    grid_wind(a, p, w);
    w[0] += U * c;
    w[1] += U * s;
    if (turbulent) {
      const double ax = v_rows[i] - w[0], ay = v_rows[n + i] - w[1], az = v_rows[2 * n + i] - w[2];
      const double V = std::max(std::sqrt(ax * ax + ay * ay + az * az), a.min_airspeed);
      const DrydenScales d = dryden_scales(p[2], a.wind_20ft);
      double* f = &filter_[5 * i];
      Rng& r = rng_[i];
      if (dt > 0.0) {
        // u: H(s) = sigma sqrt(2L/(pi V)) / (1 + (L/V) s), an exact first-order (Ornstein-Uhlenbeck) step.
        const double e = std::exp(-V * dt / d.L_u);
        f[0] = e * f[0] + std::sqrt(-std::expm1(-2.0 * V * dt / d.L_u)) * normal(r);
        // v, w: H(s) = sigma sqrt(L/(pi V)) (1 + sqrt(3) (L/V) s) / (1 + (L/V) s)^2 as a critically damped pair
        // scaled to stationary covariance I/4 (output xi1 + sqrt(3) xi2 has unit variance), stepped exactly.
        for (int k = 0; k < 2; ++k) {
          const double L = k == 0 ? d.L_v : d.L_w;
          const double q = V * dt / L, ek = std::exp(-q);
          const double P11 = ek * (1.0 + q), P12 = ek * q, P21 = -ek * q, P22 = ek * (1.0 - q);
          double* xi = f + 1 + 2 * k;
          const double x1 = P11 * xi[0] + P12 * xi[1], x2 = P21 * xi[0] + P22 * xi[1];
          // Q = (I - P P^T) / 4 and its Cholesky factor.
          const double Q11 = 0.25 * (1.0 - (P11 * P11 + P12 * P12));
          const double Q12 = -0.25 * (P11 * P21 + P12 * P22);
          const double Q22 = 0.25 * (1.0 - (P21 * P21 + P22 * P22));
          const double l11 = std::sqrt(std::max(Q11, 0.0));
          const double l21 = l11 > 0.0 ? Q12 / l11 : 0.0;
          const double l22 = std::sqrt(std::max(Q22 - l21 * l21, 0.0));
          const double n1 = normal(r), n2 = normal(r);
          xi[0] = x1 + l11 * n1;
          xi[1] = x2 + l21 * n1 + l22 * n2;
        }
      }
      const double tu = d.sigma_u * f[0];
      const double tv = d.sigma_v * (f[1] + std::sqrt(3.0) * f[2]);
      const double tw = d.sigma_w * (f[3] + std::sqrt(3.0) * f[4]);
      w[0] += c * tu - s * tv;
      w[1] += s * tu + c * tv;
      w[2] += tw;
    }
    for (const GustEvent& g : a.gusts) {
      const double gs = gust_speed(g, t);
      w[0] += gs * std::cos(g.direction);
      w[1] += gs * std::sin(g.direction);
    }
    wind_rows[i] = w[0];
    wind_rows[n + i] = w[1];
    wind_rows[2 * n + i] = w[2];
  }
}

}  // namespace cufund
