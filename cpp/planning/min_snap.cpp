#include "min_snap.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cufund::planning {

namespace {

double factorial(int r) {
  double f = 1.0;
  for (int i = 2; i <= r; ++i) f *= i;
  return f;
}

// j (j-1) ... (j-r+1): the r-th derivative of s^j at s = 1 (zero for j < r).
double falling(int j, int r) {
  if (j < r) return 0.0;
  double f = 1.0;
  for (int i = 0; i < r; ++i) f *= j - i;
  return f;
}

// A banded matrix with lower bandwidth kl and upper bandwidth ku, stored by rows relative to the diagonal
// with room for the fill-in of partial pivoting (upper bandwidth kl + ku), solved in place (LAPACK gbsv's
// algorithm: row swaps within the kl rows below the pivot, then back substitution).
class BandSystem {
 public:
  BandSystem(std::size_t n, std::size_t kl, std::size_t ku)
      : n_(n), kl_(kl), ku_(kl + ku), w_(kl + kl + ku + 1), a_(n * w_, 0.0) {}
  double& at(std::size_t i, std::size_t j) { return a_[i * w_ + (j + kl_ - i)]; }

  // Solves A X = B for B n x nrhs (row-major, overwritten with X). False if A is singular.
  bool solve(double* b, std::size_t nrhs) {
    for (std::size_t i = 0; i < n_; ++i) {
      const std::size_t last = std::min(n_ - 1, i + kl_);
      std::size_t p = i;
      double best = std::fabs(at(i, i));
      for (std::size_t r = i + 1; r <= last; ++r) {
        if (std::fabs(at(r, i)) > best) {
          best = std::fabs(at(r, i));
          p = r;
        }
      }
      if (!(best > 0.0)) return false;
      const std::size_t jend = std::min(n_ - 1, i + ku_);
      if (p != i) {
        for (std::size_t j = i; j <= jend; ++j) std::swap(at(i, j), at(p, j));
        for (std::size_t c = 0; c < nrhs; ++c) std::swap(b[i * nrhs + c], b[p * nrhs + c]);
      }
      const double piv = at(i, i);
      for (std::size_t r = i + 1; r <= last; ++r) {
        const double l = at(r, i) / piv;
        if (l == 0.0) continue;
        at(r, i) = 0.0;
        for (std::size_t j = i + 1; j <= jend; ++j) at(r, j) -= l * at(i, j);
        for (std::size_t c = 0; c < nrhs; ++c) b[r * nrhs + c] -= l * b[i * nrhs + c];
      }
    }
    for (std::size_t i = n_; i-- > 0;) {
      const std::size_t jend = std::min(n_ - 1, i + ku_);
      for (std::size_t c = 0; c < nrhs; ++c) {
        double s = b[i * nrhs + c];
        for (std::size_t j = i + 1; j <= jend; ++j) s -= at(i, j) * b[j * nrhs + c];
        b[i * nrhs + c] = s / at(i, i);
      }
    }
    return true;
  }

 private:
  std::size_t n_, kl_, ku_, w_;
  std::vector<double> a_;
};

// int_0^1 of the product of the 4th derivatives of s^a and s^b (a, b < 8).
struct SnapCostMatrix {
  double h[8][8];
  SnapCostMatrix() {
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b < 8; ++b) {
        h[a][b] = (a < 4 || b < 4) ? 0.0 : falling(a, 4) * falling(b, 4) / static_cast<double>(a + b - 8 + 1);
      }
    }
  }
};

double snap_cost_of(const std::vector<double>& c, std::size_t m, std::size_t dim, const double* T) {
  static const SnapCostMatrix H;
  double J = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    double seg = 0.0;
    for (std::size_t d = 0; d < dim; ++d) {
      for (int a = 4; a < 8; ++a) {
        const double ca = c[(i * 8 + static_cast<std::size_t>(a)) * dim + d];
        for (int b = 4; b < 8; ++b) seg += ca * H.h[a][b] * c[(i * 8 + static_cast<std::size_t>(b)) * dim + d];
      }
    }
    J += seg / std::pow(T[i], 7);
  }
  return J;
}

}  // namespace

std::vector<double> min_derivative_spline(const double* values, std::size_t m, std::size_t dim, const double* T,
                                          int order) {
  const auto k = static_cast<std::size_t>(order);
  const std::size_t nc = 2 * k, n = m * nc;
  BandSystem A(n, 3 * k - 2, k);
  std::vector<double> b(n * dim, 0.0);
  // r! and F[r][j] = d^r/ds^r s^j at s = 1, the same for every segment (order <= 8: nc <= 16)
  double fact[16], F[16][16];
  for (std::size_t r = 0; r < nc; ++r) {
    fact[r] = factorial(static_cast<int>(r));
    for (std::size_t j = 0; j < nc; ++j) F[r][j] = falling(static_cast<int>(j), static_cast<int>(r));
  }
  for (std::size_t r = 1; r < k; ++r) A.at(r - 1, r) = fact[r];  // rest at the start
  for (std::size_t i = 0; i < m; ++i) {
    const std::size_t base = i * nc, top = (k - 1) + i * nc;
    A.at(top, base) = 1.0;                                               // p_i(0) = w_i
    for (std::size_t j = 0; j < nc; ++j) A.at(top + 1, base + j) = 1.0;  // p_i(1) = w_{i+1}
    for (std::size_t d = 0; d < dim; ++d) {
      b[top * dim + d] = values[i * dim + d];
      b[(top + 1) * dim + d] = values[(i + 1) * dim + d];
    }
    // Derivatives 1..2k-2 continuous into the next segment (each row scaled by T_i^r), or 1..k-1 zero at the end.
    const std::size_t rmax = i + 1 < m ? 2 * k - 2 : k - 1;
    const double ratio = i + 1 < m ? T[i] / T[i + 1] : 0.0;
    for (std::size_t r = 1; r <= rmax; ++r) {
      for (std::size_t j = r; j < nc; ++j) A.at(top + 1 + r, base + j) = F[r][j];
      if (i + 1 < m) A.at(top + 1 + r, base + nc + r) = -fact[r] * std::pow(ratio, static_cast<double>(r));
    }
  }
  if (!A.solve(b.data(), dim)) std::fill(b.begin(), b.end(), std::numeric_limits<double>::quiet_NaN());
  return b;  // unknowns ordered segment, coefficient: exactly the m x nc x dim layout
}

double snap_cost_and_gradient(const double* values, std::size_t m, std::size_t dim, const double* T, double* grad) {
  const std::vector<double> c = min_derivative_spline(values, m, dim, T, 4);
  if (grad != nullptr) {
    for (std::size_t i = 0; i < m; ++i) {
      double dr[8];
      double H = 0.0;
      for (std::size_t d = 0; d < dim; ++d) {
        double scale = 1.0;  // r! / T^r
        for (int r = 0; r < 8; ++r) {
          if (r > 0) scale *= r / T[i];
          dr[r] = c[(i * 8 + static_cast<std::size_t>(r)) * dim + d] * scale;
        }
        H += dr[4] * dr[4] - 2.0 * dr[1] * dr[7] + 2.0 * dr[2] * dr[6] - 2.0 * dr[3] * dr[5];
      }
      grad[i] = -H;
    }
  }
  return snap_cost_of(c, m, dim, T);
}

TimeOptimizationResult optimize_segment_times(const double* values, std::size_t m, std::size_t dim,
                                              const double* durations, int max_iterations, double gtol) {
  TimeOptimizationResult res;
  res.durations.assign(durations, durations + m);
  double total = 0.0;
  for (std::size_t i = 0; i < m; ++i) total += durations[i];
  if (m < 2) return res;
  std::vector<double> T(m), dJ(m);
  // The scale-free objective over x = log T (shifted so the largest time is 1) and its gradient.
  auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
    ++res.evaluations;
    const double xmax = *std::max_element(x.begin(), x.end());
    double sum = 0.0;
    for (std::size_t i = 0; i < m; ++i) sum += (T[i] = std::exp(x[i] - xmax));
    const double J = snap_cost_and_gradient(values, m, dim, T.data(), dJ.data());
    for (std::size_t i = 0; i < m; ++i) g[i] = T[i] * (dJ[i] / J + 7.0 / sum);
    return std::log(J) + 7.0 * std::log(sum);
  };
  std::vector<double> x0(m), x(m), g(m), xn(m), gn(m), d(m), s(m), y(m), Hy(m);
  for (std::size_t i = 0; i < m; ++i) x0[i] = std::log(durations[i] / total);
  const double f0 = objective(x0, g);
  if (!std::isfinite(f0)) return res;
  x = x0;
  double f = f0;
  std::vector<double> Hinv(m * m, 0.0);  // inverse Hessian estimate, row-major
  auto reset = [&](double scale) {
    std::fill(Hinv.begin(), Hinv.end(), 0.0);
    for (std::size_t i = 0; i < m; ++i) Hinv[i * m + i] = scale;
  };
  reset(1.0);
  bool scaled = false;
  for (res.iterations = 0; res.iterations < max_iterations; ++res.iterations) {
    double gmax = 0.0, gnorm2 = 0.0;
    for (double v : g) {
      gmax = std::max(gmax, std::fabs(v));
      gnorm2 += v * v;
    }
    if (gmax <= gtol) break;
    double slope = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      double v = 0.0;
      for (std::size_t j = 0; j < m; ++j) v -= Hinv[i * m + j] * g[j];
      d[i] = v;
      slope += v * g[i];
    }
    if (!(slope < 0.0)) {  // lost positive definiteness: steepest descent again
      reset(1.0);
      scaled = false;
      slope = 0.0;
      for (std::size_t i = 0; i < m; ++i) {
        d[i] = -g[i];
        slope -= g[i] * g[i];
      }
    }
    double step = scaled ? 1.0 : std::min(1.0, 1.0 / std::sqrt(gnorm2));  // first step: at most unit length
    double fn = f;
    bool accepted = false;
    for (int ls = 0; ls < 40; ++ls) {
      for (std::size_t i = 0; i < m; ++i) xn[i] = x[i] + step * d[i];
      fn = objective(xn, gn);
      if (fn <= f + 1e-4 * step * slope) {  // Armijo (false for NaN)
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) break;
    double sy = 0.0, ss = 0.0, yy = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      s[i] = xn[i] - x[i];
      y[i] = gn[i] - g[i];
      sy += s[i] * y[i];
      ss += s[i] * s[i];
      yy += y[i] * y[i];
    }
    x.swap(xn);
    g.swap(gn);
    f = fn;
    if (!(sy > 1e-12 * std::sqrt(ss * yy))) continue;  // no positive curvature along s: keep the estimate
    if (!scaled) {  // Nocedal & Wright (6.20): the first estimate scaled to the observed curvature
      reset(sy / yy);
      scaled = true;
    }
    // H <- (I - rho s y^T) H (I - rho y s^T) + rho s s^T
    const double rho = 1.0 / sy;
    double yHy = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      double v = 0.0;
      for (std::size_t j = 0; j < m; ++j) v += Hinv[i * m + j] * y[j];
      Hy[i] = v;
      yHy += y[i] * v;
    }
    const double c = rho * rho * yHy + rho;
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t j = 0; j < m; ++j) {
        Hinv[i * m + j] += c * s[i] * s[j] - rho * (Hy[i] * s[j] + s[i] * Hy[j]);
      }
    }
  }
  const std::vector<double>& best = f <= f0 ? x : x0;
  const double xmax = *std::max_element(best.begin(), best.end());
  double sum = 0.0;
  for (std::size_t i = 0; i < m; ++i) sum += (T[i] = std::exp(best[i] - xmax));
  for (std::size_t i = 0; i < m; ++i) res.durations[i] = T[i] * (total / sum);
  return res;
}

}  // namespace cufund::planning
