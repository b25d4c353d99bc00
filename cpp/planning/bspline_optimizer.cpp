#include "bspline_optimizer.h"

#include <algorithm>
#include <cmath>
#include <deque>

namespace cufund::planning {

namespace {

using Vec = std::vector<double>;

double dot(const Vec& a, const Vec& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

Vec flatten(const std::vector<Vec3>& x) {
  Vec v(3 * x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) v[3 * i + a] = x[i][a];
  }
  return v;
}

std::vector<Vec3> unflatten(const Vec& v) {
  std::vector<Vec3> x(v.size() / 3);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
  return x;
}

}  // namespace

double bspline_cost(const esdf::EsdfMap& map, const BsplineProblem& pb, const BsplineWeights& w,
                    const std::vector<Vec3>& x, std::vector<Vec3>* grad) {
  const std::size_t ns = pb.start.size(), nx = x.size();
  std::vector<Vec3> q;
  q.reserve(ns + nx + pb.tail.size());
  q.insert(q.end(), pb.start.begin(), pb.start.end());
  q.insert(q.end(), x.begin(), x.end());
  q.insert(q.end(), pb.tail.begin(), pb.tail.end());
  const std::size_t n = q.size();
  std::vector<Vec3> g(n, Vec3{0.0, 0.0, 0.0});
  double f = 0.0;
  for (std::size_t a = 0; a < 3; ++a) {
    // Smoothness: jerk control points.
    for (std::size_t i = 0; i + 3 < n; ++i) {
      const double j = q[i + 3][a] - 3.0 * q[i + 2][a] + 3.0 * q[i + 1][a] - q[i][a];
      f += w.smooth * j * j;
      const double gj = 2.0 * w.smooth * j;
      g[i + 3][a] += gj;
      g[i + 2][a] -= 3.0 * gj;
      g[i + 1][a] += 3.0 * gj;
      g[i][a] -= gj;
    }
    // Feasibility per axis: velocity and acceleration control points beyond the limits.
    for (std::size_t i = 0; i + 1 < n; ++i) {
      const double v = (q[i + 1][a] - q[i][a]) / w.dt;
      const double e = std::max(std::fabs(v) - w.v_max, 0.0);
      if (e > 0.0) {
        f += w.feasibility * e * e;
        const double gv = 2.0 * w.feasibility * e * (v > 0 ? 1.0 : -1.0) / w.dt;
        g[i + 1][a] += gv;
        g[i][a] -= gv;
      }
    }
    for (std::size_t i = 0; i + 2 < n; ++i) {
      const double acc = (q[i + 2][a] - 2.0 * q[i + 1][a] + q[i][a]) / (w.dt * w.dt);
      const double e = std::max(std::fabs(acc) - w.a_max, 0.0);
      if (e > 0.0) {
        f += w.feasibility * e * e;
        const double ga = 2.0 * w.feasibility * e * (acc > 0 ? 1.0 : -1.0) / (w.dt * w.dt);
        g[i + 2][a] += ga;
        g[i + 1][a] -= 2.0 * ga;
        g[i][a] += ga;
      }
    }
  }
  // Collision at the free control points: the map's trilinear distance and its exact gradient.
  if (nx > 0) {
    std::vector<double> d(nx), dg(3 * nx);
    map.query(&x[0][0], static_cast<std::ptrdiff_t>(nx), d.data(), dg.data());
    for (std::size_t i = 0; i < nx; ++i) {
      const double di = std::isfinite(d[i]) ? d[i] : 1e9;  // +inf: nothing occupied
      const double e = std::max(w.d_safe - di, 0.0);
      if (e > 0.0) {
        f += w.collision * e * e * e;
        for (std::size_t a = 0; a < 3; ++a) g[ns + i][a] -= 3.0 * w.collision * e * e * dg[3 * i + a];
      }
    }
  }
  if (pb.pull_end && nx > 0) {
    for (std::size_t a = 0; a < 3; ++a) {
      const double r = x[nx - 1][a] - pb.end_target[a];
      f += w.end * r * r;
      g[ns + nx - 1][a] += 2.0 * w.end * r;
    }
  }
  if (grad) grad->assign(g.begin() + static_cast<std::ptrdiff_t>(ns), g.begin() + static_cast<std::ptrdiff_t>(ns + nx));
  return f;
}

BsplineResult optimize_bspline(const esdf::EsdfMap& map, const BsplineProblem& pb, const BsplineWeights& w,
                               const std::vector<Vec3>& initial, const LbfgsOptions& opt) {
  BsplineResult res;
  Vec x = flatten(initial);
  std::vector<Vec3> gv;
  auto eval = [&](const Vec& xv, Vec* gout) {
    ++res.evaluations;
    const double f = bspline_cost(map, pb, w, unflatten(xv), &gv);
    *gout = flatten(gv);
    return f;
  };
  Vec g;
  double f = eval(x, &g);
  std::deque<Vec> S, Y;
  std::deque<double> rho;
  const std::size_t dim = x.size();
  Vec d(dim), xn(dim), gn(dim);
  for (res.iterations = 0; res.iterations < opt.max_iterations; ++res.iterations) {
    double gmax = 0.0;
    for (double v : g) gmax = std::max(gmax, std::fabs(v));
    if (gmax <= opt.gradient_tolerance * std::max(1.0, std::fabs(f))) break;
    // Two-loop recursion: d = -H g.
    d = g;
    std::vector<double> alpha(S.size());
    for (std::size_t k = S.size(); k-- > 0;) {
      alpha[k] = rho[k] * dot(S[k], d);
      for (std::size_t i = 0; i < dim; ++i) d[i] -= alpha[k] * Y[k][i];
    }
    if (!S.empty()) {
      const double gamma = dot(S.back(), Y.back()) / dot(Y.back(), Y.back());
      for (double& v : d) v *= gamma;
    } else {
      const double scale = 1.0 / std::max(1.0, std::sqrt(dot(g, g)));  // a first step of at most 1 m
      for (double& v : d) v *= scale;
    }
    for (std::size_t k = 0; k < S.size(); ++k) {
      const double beta = rho[k] * dot(Y[k], d);
      for (std::size_t i = 0; i < dim; ++i) d[i] += (alpha[k] - beta) * S[k][i];
    }
    for (double& v : d) v = -v;
    double slope = dot(g, d);
    if (!(slope < 0.0)) {  // not a descent direction: restart from steepest descent
      S.clear();
      Y.clear();
      rho.clear();
      const double scale = 1.0 / std::max(1.0, std::sqrt(dot(g, g)));
      for (std::size_t i = 0; i < dim; ++i) d[i] = -g[i] * scale;
      slope = dot(g, d);
    }
    // Backtracking Armijo line search.
    double step = 1.0, fn = f;
    bool accepted = false;
    for (int ls = 0; ls < 30; ++ls) {
      for (std::size_t i = 0; i < dim; ++i) xn[i] = x[i] + step * d[i];
      fn = eval(xn, &gn);
      if (fn <= f + 1e-4 * step * slope) {
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) break;
    Vec s(dim), y(dim);
    for (std::size_t i = 0; i < dim; ++i) {
      s[i] = xn[i] - x[i];
      y[i] = gn[i] - g[i];
    }
    const double sy = dot(s, y);
    if (sy > 1e-12 * std::sqrt(dot(s, s) * dot(y, y))) {  // keep the curvature pair only if positive
      S.push_back(std::move(s));
      Y.push_back(std::move(y));
      rho.push_back(1.0 / sy);
      if (static_cast<int>(S.size()) > opt.memory) {
        S.pop_front();
        Y.pop_front();
        rho.pop_front();
      }
    }
    const double df = f - fn;
    x.swap(xn);
    g.swap(gn);
    f = fn;
    if (df <= opt.relative_decrease * std::max(1.0, std::fabs(f))) break;
  }
  res.free = unflatten(x);
  res.cost = f;
  return res;
}

}  // namespace cufund::planning
