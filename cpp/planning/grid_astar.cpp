#include "grid_astar.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <queue>
#include <tuple>

namespace cufund::planning {

using Index = std::ptrdiff_t;

namespace {

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// Octile distance on the 26-connected grid [voxels]: the shortest grid path ignoring obstacles.
double octile(Index dx, Index dy, Index dz) {
  Index a = std::abs(dx), b = std::abs(dy), c = std::abs(dz);
  if (a < b) std::swap(a, b);
  if (b < c) std::swap(b, c);
  if (a < b) std::swap(a, b);  // a >= b >= c
  return static_cast<double>(a - b) + std::sqrt(2.0) * static_cast<double>(b - c) +
         std::sqrt(3.0) * static_cast<double>(c);
}

struct Entry {
  double f;
  double h;
  Index index;
  bool operator>(const Entry& o) const { return std::tie(f, h, index) > std::tie(o.f, o.h, o.index); }
};

// The voxel holding p (clamped to the grid).
std::array<Index, 3> voxel_of(const esdf::GridGeometry& g, const Vec3& p) {
  std::array<Index, 3> v{};
  for (std::size_t a = 0; a < 3; ++a) {
    const double u = std::floor((p[a] - g.origin_W[a]) / g.resolution);
    v[a] = static_cast<Index>(std::clamp(u, 0.0, static_cast<double>(g.shape[a] - 1)));
  }
  return v;
}

}  // namespace

double path_length(const std::vector<Vec3>& path) {
  double s = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) s += distance(path[i - 1], path[i]);
  return s;
}

double GridAStar::node_clearance(const ClearanceMap& map, Index linear, AStarResult& result) {
  float& c = clearance_[static_cast<std::size_t>(linear)];
  if (std::isnan(c)) {
    const auto& g = map.geometry();
    const Index k = linear % g.shape[2], j = (linear / g.shape[2]) % g.shape[1], i = linear / (g.shape[1] * g.shape[2]);
    // Rounded down to float so the cached value never exceeds the certified bound.
    const double d = map.clearance(map.centre(i, j, k));
    float f = static_cast<float>(d);
    if (static_cast<double>(f) > d) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    c = f;
    ++result.clearance_queries;
  }
  return static_cast<double>(c);
}

AStarResult GridAStar::plan(const ClearanceMap& map, const Vec3& start, const Vec3& goal, const AStarOptions& opt) {
  AStarResult result;
  const auto& g = map.geometry();
  const double h = g.resolution;
  const double r = opt.radius;
  if (!(map.clearance(start) >= r)) {
    result.status = PathStatus::kStartBlocked;
    return result;
  }
  if (!(map.clearance(goal) >= r)) {
    result.status = PathStatus::kGoalBlocked;
    return result;
  }
  if (map.segment_free(start, goal, r)) {
    result.status = PathStatus::kFound;
    result.path = {start, goal};
    result.length = distance(start, goal);
    return result;
  }
  const Index n = g.shape[0] * g.shape[1] * g.shape[2];
  if (size_ != n) {
    const auto un = static_cast<std::size_t>(n);
    stamp_.reset(static_cast<std::uint32_t*>(std::calloc(un, sizeof(std::uint32_t))));
    g_.reset(static_cast<float*>(std::malloc(un * sizeof(float))));
    clearance_.reset(static_cast<float*>(std::malloc(un * sizeof(float))));
    parent_.reset(static_cast<std::int64_t*>(std::malloc(un * sizeof(std::int64_t))));
    closed_.reset(static_cast<std::uint8_t*>(std::malloc(un)));
    if (!stamp_ || !g_ || !clearance_ || !parent_ || !closed_) {
      size_ = 0;
      throw std::bad_alloc();
    }
    size_ = n;
    generation_ = 0;
  }
  if (++generation_ == 0) {  // wrapped: clear the stamps once every 2^32 searches
    std::fill(stamp_.get(), stamp_.get() + size_, 0u);
    generation_ = 1;
  }
  auto touch = [&](Index i) {
    const auto s = static_cast<std::size_t>(i);
    if (stamp_[s] != generation_) {
      stamp_[s] = generation_;
      g_[s] = std::numeric_limits<float>::infinity();
      clearance_[s] = std::numeric_limits<float>::quiet_NaN();
      parent_[s] = -1;
      closed_[s] = 0;
    }
  };
  const auto gv = voxel_of(g, goal);
  const double hw = h * std::max(1.0, opt.heuristic_weight);
  auto heuristic = [&](Index i, Index j, Index k) { return hw * octile(i - gv[0], j - gv[1], k - gv[2]); };
  auto lin = [&](Index i, Index j, Index k) { return (i * g.shape[1] + j) * g.shape[2] + k; };
  auto in_grid = [&](Index i, Index j, Index k) {
    if (!(i >= 0 && j >= 0 && k >= 0 && i < g.shape[0] && j < g.shape[1] && k < g.shape[2])) return false;
    const double z = g.origin_W[2] + (static_cast<double>(k) + 0.5) * h;
    return z >= opt.z_min && z <= opt.z_max;  // the height band (infinite by default)
  };

  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  // Goal set: voxels around the goal that a free segment joins to it, with that segment's length.
  std::vector<std::pair<Index, double>> goal_links;
  for (Index di = -1; di <= 1; ++di) {
    for (Index dj = -1; dj <= 1; ++dj) {
      for (Index dk = -1; dk <= 1; ++dk) {
        const Index i = gv[0] + di, j = gv[1] + dj, k = gv[2] + dk;
        if (!in_grid(i, j, k)) continue;
        const Vec3 c = map.centre(i, j, k);
        if (map.segment_free(c, goal, r)) goal_links.emplace_back(lin(i, j, k), distance(c, goal));
      }
    }
  }
  if (goal_links.empty()) {
    result.status = PathStatus::kGoalBlocked;
    return result;
  }
  std::sort(goal_links.begin(), goal_links.end());
  auto goal_link = [&](Index i) -> double {
    auto it = std::lower_bound(goal_links.begin(), goal_links.end(), std::make_pair(i, -1.0));
    return it != goal_links.end() && it->first == i ? it->second : -1.0;
  };
  const auto sv = voxel_of(g, start);
  bool seeded = false;
  for (Index di = -1; di <= 1; ++di) {
    for (Index dj = -1; dj <= 1; ++dj) {
      for (Index dk = -1; dk <= 1; ++dk) {
        const Index i = sv[0] + di, j = sv[1] + dj, k = sv[2] + dk;
        if (!in_grid(i, j, k)) continue;
        const Vec3 c = map.centre(i, j, k);
        if (!map.segment_free(start, c, r)) continue;
        const Index id = lin(i, j, k);
        touch(id);
        const double gc = distance(start, c);
        g_[static_cast<std::size_t>(id)] = static_cast<float>(gc);
        parent_[static_cast<std::size_t>(id)] = -1;
        open.push({gc + heuristic(i, j, k), heuristic(i, j, k), id});
        seeded = true;
      }
    }
  }
  if (!seeded) {
    result.status = PathStatus::kStartBlocked;
    return result;
  }

  Index best_goal = -1;
  double best_cost = std::numeric_limits<double>::infinity();
  while (!open.empty()) {
    const Entry e = open.top();
    open.pop();
    if (e.f >= best_cost) break;  // no open node can improve the best complete path
    const auto s = static_cast<std::size_t>(e.index);
    if (closed_[s]) continue;
    closed_[s] = 1;
    if (++result.expansions > opt.max_expansions) {
      result.status = PathStatus::kExpansionLimit;
      return result;
    }
    const double gcur = static_cast<double>(g_[s]);
    const double link = goal_link(e.index);
    if (link >= 0.0 && gcur + link < best_cost) {
      best_cost = gcur + link;
      best_goal = e.index;
    }
    const Index k0 = e.index % g.shape[2], j0 = (e.index / g.shape[2]) % g.shape[1],
                i0 = e.index / (g.shape[1] * g.shape[2]);
    const Vec3 c0 = map.centre(i0, j0, k0);
    const double cl0 = node_clearance(map, e.index, result);
    for (Index di = -1; di <= 1; ++di) {
      for (Index dj = -1; dj <= 1; ++dj) {
        for (Index dk = -1; dk <= 1; ++dk) {
          if (di == 0 && dj == 0 && dk == 0) continue;
          const Index i = i0 + di, j = j0 + dj, k = k0 + dk;
          if (!in_grid(i, j, k)) continue;
          const Index id = lin(i, j, k);
          touch(id);
          const auto t = static_cast<std::size_t>(id);
          if (closed_[t]) continue;
          const double step = h * std::sqrt(static_cast<double>(di * di + dj * dj + dk * dk));
          const double ng = gcur + step;
          if (ng >= static_cast<double>(g_[t])) continue;
          const double cl = node_clearance(map, id, result);
          if (!(cl >= r)) continue;
          // Every edge point is within step/2 of an end, so ends clearing r + step/2 certify the edge.
          const bool free = std::min(cl, cl0) >= r + 0.5 * step || map.segment_free(c0, map.centre(i, j, k), r);
          if (!free) continue;
          g_[t] = static_cast<float>(ng);
          parent_[t] = e.index;
          const double hh = heuristic(i, j, k);
          open.push({ng + hh, hh, id});
        }
      }
    }
  }
  if (best_goal < 0) {
    result.status = PathStatus::kNoPath;
    return result;
  }
  std::vector<Vec3> path{goal};
  for (Index i = best_goal; i >= 0; i = parent_[static_cast<std::size_t>(i)]) {
    const Index k = i % g.shape[2], j = (i / g.shape[2]) % g.shape[1], ii = i / (g.shape[1] * g.shape[2]);
    path.push_back(map.centre(ii, j, k));
  }
  path.push_back(start);
  std::reverse(path.begin(), path.end());
  if (opt.shortcut) path = relax_path(map, shortcut_path(map, path, r), r, opt.z_min, opt.z_max);
  result.status = PathStatus::kFound;
  result.length = path_length(path);
  result.path = std::move(path);
  return result;
}

std::vector<Vec3> shortcut_path(const ClearanceMap& map, const std::vector<Vec3>& path, double radius) {
  if (path.size() <= 2) return path;
  std::vector<Vec3> out{path.front()};
  std::size_t i = 0;
  while (i + 1 < path.size()) {
    std::size_t j = i + 1;
    while (j + 1 < path.size() && map.segment_free(path[i], path[j + 1], radius)) ++j;
    out.push_back(path[j]);
    i = j;
  }
  return out;
}

std::vector<Vec3> relax_path(const ClearanceMap& map, const std::vector<Vec3>& path, double radius, double z_min,
                             double z_max, double max_segment, int iterations) {
  if (path.size() <= 2) return path;
  std::vector<Vec3> p{path.front()};
  for (std::size_t s = 1; s < path.size(); ++s) {
    const Vec3 &a = path[s - 1], &b = path[s];
    const int n = std::max(1, static_cast<int>(std::ceil(distance(a, b) / max_segment)));
    for (int k = 1; k < n; ++k) {
      const double u = static_cast<double>(k) / n;
      p.push_back({a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])});
    }
    p.push_back(b);
  }
  // How far a height lies outside the band [m]: a move may not take a vertex further out.
  const auto out_of_band = [&](double z) { return std::max({z_min - z, z - z_max, 0.0}); };
  const double tiny = map.min_step();
  for (int it = 0; it < iterations; ++it) {
    bool moved = false;
    for (std::size_t i = 1; i + 1 < p.size(); ++i) {
      const Vec3 &a = p[i - 1], &b = p[i + 1], c = p[i];
      Vec3 ab{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const double ab2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
      double u = 0.0;
      if (ab2 > 0.0)
        u = std::clamp(((c[0] - a[0]) * ab[0] + (c[1] - a[1]) * ab[1] + (c[2] - a[2]) * ab[2]) / ab2, 0.0, 1.0);
      const Vec3 d{a[0] + u * ab[0] - c[0], a[1] + u * ab[1] - c[1], a[2] + u * ab[2] - c[2]};
      if (std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) < tiny) continue;
      for (double t = 1.0; t >= 0.125; t *= 0.5) {
        const Vec3 q{c[0] + t * d[0], c[1] + t * d[1], c[2] + t * d[2]};
        if (out_of_band(q[2]) > out_of_band(c[2])) continue;
        if (map.segment_free(a, q, radius) && map.segment_free(q, b, radius)) {
          p[i] = q;
          moved = true;
          break;
        }
      }
    }
    if (!moved) break;
  }
  return shortcut_path(map, p, radius);
}

}  // namespace cufund::planning
