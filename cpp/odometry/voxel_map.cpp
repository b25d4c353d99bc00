#include "voxel_map.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "imu_propagation.h"
#include "thread_pool.h"

namespace cufund::odometry {

namespace {

constexpr std::int64_t kHalfRange = std::int64_t{1} << 20;

std::int64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return ((x + kHalfRange) << 42) | ((y + kHalfRange) << 21) | (z + kHalfRange);
}

bool voxel_index(const Eigen::Vector3d& p, double inv_voxel, Eigen::Matrix<std::int64_t, 3, 1>& idx) {
  for (int i = 0; i < 3; ++i) {
    // floor(f) by truncation (no libm call on baseline x86-64): the range test on f is the one on floor(f),
    // the bounds being integers.
    const double f = p[i] * inv_voxel;
    if (!(f >= -static_cast<double>(kHalfRange) + 1 && f < static_cast<double>(kHalfRange) - 1)) return false;
    std::int64_t k = static_cast<std::int64_t>(f);
    if (static_cast<double>(k) > f) --k;
    idx[i] = k;
  }
  return true;
}

// Offsets o = 9 (dx + 1) + 3 (dy + 1) + (dz + 1) of the 27 voxels around a voxel, by |dx| + |dy| + |dz|.
constexpr int kNeighbourOrder[27] = {13, 4,  10, 12, 14, 16, 22, 1, 3, 5,  7,  9,  11, 15,
                                     17, 19, 21, 23, 25, 0,  2,  6, 8, 18, 20, 24, 26};

double robust_weight(Robust kind, double r, double c) {
  const double a = std::abs(r);
  switch (kind) {
    case Robust::kHuber: return a <= c ? 1.0 : c / a;
    case Robust::kCauchy: return 1.0 / (1.0 + (r / c) * (r / c));
    case Robust::kNone: break;
  }
  return 1.0;
}

}  // namespace

bool voxel_key(const Eigen::Vector3d& p, double inv_voxel, std::int64_t& key) {
  Eigen::Matrix<std::int64_t, 3, 1> idx;
  if (!voxel_index(p, inv_voxel, idx)) return false;
  key = pack(idx[0], idx[1], idx[2]);
  return true;
}

namespace {
constexpr std::int64_t kEmpty = std::numeric_limits<std::int64_t>::min();

// Fibonacci hashing: the product's top bits (a table of 2^(64 - shift) slots) depend on every bit of the key;
// its low bits would ignore a packed key's x and most of its y (long probe runs along x).
std::size_t hash_slot(std::int64_t key, unsigned shift) {
  return static_cast<std::size_t>((static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ull) >> shift);
}

unsigned shift_for(std::size_t capacity) {  // capacity: a power of two >= 2
  unsigned bits = 0;
  while ((std::size_t{1} << bits) < capacity) ++bits;
  return 64u - bits;
}
}  // namespace

std::vector<double> voxel_downsample(const double* points, std::size_t n, double voxel) {
  // Open addressing (linear probing) from voxel key to output index: no allocation per voxel. Sums start at
  // the first point and add the others in input order.
  const double inv = 1.0 / voxel;
  std::size_t cap = 16;
  while (cap < 2 * n) cap *= 2;
  const std::size_t mask = cap - 1;
  const unsigned shift = shift_for(cap);
  constexpr std::int64_t kFree = std::numeric_limits<std::int64_t>::min();
  std::vector<std::int64_t> table_keys(cap, kFree);
  std::vector<std::uint32_t> table_index(cap);
  std::vector<double> sums;
  std::vector<std::uint32_t> counts;
  sums.reserve(3 * std::min<std::size_t>(n, 1 << 16));
  counts.reserve(std::min<std::size_t>(n, 1 << 16));
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(points[3 * i], points[3 * i + 1], points[3 * i + 2]);
    Eigen::Matrix<std::int64_t, 3, 1> idx;
    if (!voxel_index(p, inv, idx)) continue;
    const std::int64_t key = pack(idx[0], idx[1], idx[2]);
    std::size_t s = hash_slot(key, shift);
    while (table_keys[s] != kFree && table_keys[s] != key) s = (s + 1) & mask;
    if (table_keys[s] == kFree) {
      table_keys[s] = key;
      table_index[s] = static_cast<std::uint32_t>(counts.size());
      sums.insert(sums.end(), {p.x(), p.y(), p.z()});
      counts.push_back(1);
    } else {
      double* sum = sums.data() + 3 * static_cast<std::size_t>(table_index[s]);
      sum[0] += p.x();
      sum[1] += p.y();
      sum[2] += p.z();
      ++counts[table_index[s]];
    }
  }
  std::vector<double> out(sums.size());
  for (std::size_t j = 0; j < counts.size(); ++j) {
    const double c = static_cast<double>(counts[j]);
    for (int a = 0; a < 3; ++a) out[3 * j + a] = sums[3 * j + a] / c;
  }
  return out;
}

VoxelMap::VoxelMap(double voxel_size, int max_points_per_voxel, double min_point_distance, double max_distance,
                   std::size_t max_voxels)
    : voxel_(voxel_size),
      inv_voxel_(1.0 / voxel_size),
      min_d2_(min_point_distance * min_point_distance),
      max_distance_(max_distance),
      max_per_voxel_(max_points_per_voxel),
      max_voxels_(max_voxels) {
  rebuild_table(1024);
}

void VoxelMap::clear() {
  keys_.clear();
  counts_.clear();
  centres_.clear();
  slots_.clear();
  points_ = 0;
  rebuild_table(1024);
}

std::int32_t VoxelMap::find(std::int64_t key) const {
  for (std::size_t s = hash_slot(key, table_shift_);; s = (s + 1) & table_mask_) {
    if (table_keys_[s] == key) return table_index_[s];
    if (table_keys_[s] == kEmpty) return -1;
  }
}

void VoxelMap::table_insert(std::int64_t key, std::int32_t index) {
  std::size_t s = hash_slot(key, table_shift_);
  while (table_keys_[s] != kEmpty) s = (s + 1) & table_mask_;
  table_keys_[s] = key;
  table_index_[s] = index;
}

void VoxelMap::rebuild_table(std::size_t capacity) {
  std::size_t cap = 1024;
  while (cap < capacity) cap *= 2;
  table_keys_.assign(cap, kEmpty);
  table_index_.assign(cap, -1);
  table_mask_ = cap - 1;
  table_shift_ = shift_for(cap);
  for (std::size_t i = 0; i < keys_.size(); ++i) table_insert(keys_[i], static_cast<std::int32_t>(i));
}

std::size_t VoxelMap::insert(const double* points_W, std::size_t n, const Eigen::Vector3d& origin) {
  std::size_t kept = 0;
  Eigen::Matrix<std::int64_t, 3, 1> idx;
  const auto per = static_cast<std::size_t>(max_per_voxel_);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(points_W[3 * i], points_W[3 * i + 1], points_W[3 * i + 2]);
    if (!voxel_index(p, inv_voxel_, idx)) continue;
    const std::int64_t key = pack(idx[0], idx[1], idx[2]);
    std::int32_t v = find(key);
    if (v < 0) {
      v = static_cast<std::int32_t>(keys_.size());
      keys_.push_back(key);
      counts_.push_back(0);
      centres_.push_back((idx.cast<double>().array() + 0.5).matrix() * voxel_);
      slots_.resize(slots_.size() + 3 * per);
      if (2 * keys_.size() > table_keys_.size()) {
        rebuild_table(4 * keys_.size());
      } else {
        table_insert(key, v);
      }
    }
    int& count = counts_[static_cast<std::size_t>(v)];
    if (count >= max_per_voxel_) continue;
    const double* base = slots_.data() + static_cast<std::size_t>(v) * 3 * per;
    bool near = false;
    for (int j = 0; j < count && !near; ++j)
      near = (Eigen::Map<const Eigen::Vector3d>(base + 3 * j) - p).squaredNorm() < min_d2_;
    if (near) continue;
    Eigen::Map<Eigen::Vector3d>(slots_.data() + static_cast<std::size_t>(v) * 3 * per +
                                3 * static_cast<std::size_t>(count)) = p;
    ++count;
    ++points_;
    ++kept;
  }
  evict(origin);
  return kept;
}

void VoxelMap::evict(const Eigen::Vector3d& origin) {
  const std::size_t n = keys_.size();
  std::vector<std::uint8_t> keep(n, 1);
  const double r2 = max_distance_ * max_distance_;
  std::size_t alive = 0;
  for (std::size_t i = 0; i < n; ++i) {
    keep[i] = (centres_[i] - origin).squaredNorm() <= r2;
    alive += keep[i];
  }
  if (alive > max_voxels_) {
    std::vector<std::pair<double, std::size_t>> far;
    far.reserve(alive);
    for (std::size_t i = 0; i < n; ++i) {
      if (keep[i]) far.emplace_back((centres_[i] - origin).squaredNorm(), i);
    }
    const std::size_t drop = alive - max_voxels_;
    std::nth_element(far.begin(), far.begin() + static_cast<std::ptrdiff_t>(drop), far.end(),
                     [&](const auto& a, const auto& b) {
                       return a.first > b.first || (a.first == b.first && keys_[a.second] > keys_[b.second]);
                     });
    for (std::size_t i = 0; i < drop; ++i) keep[far[i].second] = 0;
    alive = max_voxels_;
  }
  if (alive == n) return;
  // Compact in place, keeping the insertion order.
  const auto per3 = 3 * static_cast<std::size_t>(max_per_voxel_);
  std::size_t w = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!keep[i]) {
      points_ -= static_cast<std::size_t>(counts_[i]);
      continue;
    }
    if (w != i) {
      keys_[w] = keys_[i];
      counts_[w] = counts_[i];
      centres_[w] = centres_[i];
      std::copy(slots_.begin() + static_cast<std::ptrdiff_t>(i * per3),
                slots_.begin() + static_cast<std::ptrdiff_t>((i + 1) * per3),
                slots_.begin() + static_cast<std::ptrdiff_t>(w * per3));
    }
    ++w;
  }
  keys_.resize(w);
  counts_.resize(w);
  centres_.resize(w);
  slots_.resize(w * per3);
  rebuild_table(2 * w);
}

std::vector<double> VoxelMap::points() const {
  std::vector<double> out;
  out.reserve(3 * points_);
  const auto per3 = 3 * static_cast<std::size_t>(max_per_voxel_);
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    out.insert(out.end(), slots_.begin() + static_cast<std::ptrdiff_t>(i * per3),
               slots_.begin() + static_cast<std::ptrdiff_t>(i * per3 + 3 * static_cast<std::size_t>(counts_[i])));
  }
  return out;
}

int VoxelMap::nearest(const Eigen::Vector3d& query, int k, double max_d2, Eigen::Vector3d* out, double* d2) const {
  Eigen::Matrix<std::int64_t, 3, 1> idx;
  if (!voxel_index(query, inv_voxel_, idx)) return 0;
  // Offsets of the query inside its voxel, to skip neighbour voxels that cannot hold a closer point.
  Eigen::Vector3d lo, hi;  // distance to the voxel's lower and upper faces, per axis
  for (int a = 0; a < 3; ++a) {
    lo[a] = query[a] - static_cast<double>(idx[a]) * voxel_;
    hi[a] = voxel_ - lo[a];
  }
  // The own voxel first, then the 6 face, 12 edge and 8 corner neighbours: the bound of the k-th nearest
  // tightens early, so more of the farther voxels are skipped. (The order does not change the result: the k
  // nearest within max_d2, ascending.)
  int found = 0;
  const double* at[kMaxNeighbours];  // k <= kMaxNeighbours: checked by knn and fit_planes
  for (const int o : kNeighbourOrder) {
    const int dx = o / 9 - 1, dy = (o / 3) % 3 - 1, dz = o % 3 - 1;
    const double gx = dx < 0 ? lo[0] : (dx > 0 ? hi[0] : 0.0);
    const double gy = dy < 0 ? lo[1] : (dy > 0 ? hi[1] : 0.0);
    const double gz = dz < 0 ? lo[2] : (dz > 0 ? hi[2] : 0.0);
    const double bound = found == k ? d2[k - 1] : max_d2;
    if (gx * gx + gy * gy + gz * gz > bound) continue;
    const std::int32_t v = find(pack(idx[0] + dx, idx[1] + dy, idx[2] + dz));
    if (v < 0) continue;
    const double* base = slots_.data() + static_cast<std::size_t>(v) * 3 * static_cast<std::size_t>(max_per_voxel_);
    const int count = counts_[static_cast<std::size_t>(v)];
    for (int m2 = 0; m2 < count; ++m2) {
      const double* p = base + 3 * m2;
      const double ex = p[0] - query[0], ey = p[1] - query[1], ez = p[2] - query[2];
      const double d = ex * ex + ey * ey + ez * ez;
      if (d > max_d2 || (found == k && d >= d2[k - 1])) continue;
      // Insertion into the sorted list (of pointers: the points are copied out once, at the end).
      int j = found < k ? found++ : k - 1;
      while (j > 0 && d2[j - 1] > d) {
        d2[j] = d2[j - 1];
        at[j] = at[j - 1];
        --j;
      }
      d2[j] = d;
      at[j] = p;
    }
  }
  for (int j = 0; j < found; ++j) out[j] = Eigen::Map<const Eigen::Vector3d>(at[j]);
  return found;
}

void VoxelMap::knn(const double* queries, std::size_t q, int k, double max_distance, double* neighbours, double* dist2,
                   int threads) const {
  if (k < 1 || k > kMaxNeighbours) throw std::invalid_argument("knn: k must be in [1, 64]");
  const double md = std::min(max_distance, voxel_);
  parallel_chunks(
      static_cast<std::ptrdiff_t>(q), 256, threads, [&](std::ptrdiff_t b, std::ptrdiff_t e, std::ptrdiff_t) {
        std::vector<Eigen::Vector3d> nb(static_cast<std::size_t>(k));
        for (std::ptrdiff_t i = b; i < e; ++i) {
          double* d2 = dist2 + i * k;
          const int found = nearest(Eigen::Map<const Eigen::Vector3d>(queries + 3 * i), k, md * md, nb.data(), d2);
          for (int j = 0; j < k; ++j) {
            double* o = neighbours + (i * k + j) * 3;
            if (j < found) {
              o[0] = nb[j].x();
              o[1] = nb[j].y();
              o[2] = nb[j].z();
            } else {
              d2[j] = std::numeric_limits<double>::infinity();
              o[0] = o[1] = o[2] = std::numeric_limits<double>::quiet_NaN();
            }
          }
        }
      });
}

void VoxelMap::fit_planes(const double* points_I, std::size_t n, const Eigen::Matrix3d& R_WI,
                          const Eigen::Vector3d& t_W, const PlaneParams& prm, std::uint8_t* valid, double* planes,
                          int threads) const {
  const int k = prm.neighbours;
  if (k < 1 || k > kMaxNeighbours) throw std::invalid_argument("fit_planes: neighbours must be in [1, 64]");
  const double md = std::min(prm.max_neighbour_distance, voxel_);
  parallel_chunks(static_cast<std::ptrdiff_t>(n), 256, threads,
                  [&](std::ptrdiff_t b, std::ptrdiff_t e, std::ptrdiff_t) {
                    std::vector<Eigen::Vector3d> nb(static_cast<std::size_t>(k));
                    std::vector<double> d2(static_cast<std::size_t>(k));
                    for (std::ptrdiff_t i = b; i < e; ++i) {
                      valid[i] = 0;
                      double* pl = planes + 4 * i;
                      pl[0] = pl[1] = pl[2] = pl[3] = 0.0;
                      const Eigen::Vector3d x = R_WI * Eigen::Map<const Eigen::Vector3d>(points_I + 3 * i) + t_W;
                      if (nearest(x, k, md * md, nb.data(), d2.data()) < k) continue;
                      Eigen::Vector3d c0 = Eigen::Vector3d::Zero();
                      for (const auto& p : nb) c0 += p;
                      c0 /= k;
                      Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
                      for (const auto& p : nb) C += (p - c0) * (p - c0).transpose();
                      C /= k;
                      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
                      es.computeDirect(C);
                      if (!(es.eigenvalues()[0] <= prm.max_plane_rms * prm.max_plane_rms)) continue;
                      // A line (two small eigenvalues) has no plane.
                      if (es.eigenvalues()[1] < 4.0 * es.eigenvalues()[0] + 1e-12) continue;
                      const Eigen::Vector3d nrm = es.eigenvectors().col(0).normalized();
                      valid[i] = 1;
                      pl[0] = nrm.x();
                      pl[1] = nrm.y();
                      pl[2] = nrm.z();
                      pl[3] = -nrm.dot(c0);
                    }
                  });
}

PlaneTerms plane_terms(const double* points_I, const double* planes, const std::uint8_t* fitted, std::size_t n,
                       const Eigen::Matrix3d& R_WI, const Eigen::Vector3d& t_W, const PlaneParams& prm, int threads) {
  PlaneTerms out;
  out.valid.assign(n, 0);
  out.residual.assign(n, 0.0);
  out.normal.assign(3 * n, 0.0);
  out.weight.assign(n, 0.0);
  const double inv_s2 = 1.0 / (prm.sigma * prm.sigma);
  constexpr std::ptrdiff_t kChunk = 1024;
  const auto chunks = static_cast<std::size_t>((static_cast<std::ptrdiff_t>(n) + kChunk - 1) / kChunk);
  struct Partial {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    double cost = 0.0;
    std::size_t inliers = 0;
  };
  std::vector<Partial> parts(chunks);
  parallel_chunks(static_cast<std::ptrdiff_t>(n), kChunk, threads,
                  [&](std::ptrdiff_t b, std::ptrdiff_t e, std::ptrdiff_t c) {
                    Partial& part = parts[static_cast<std::size_t>(c)];
                    for (std::ptrdiff_t i = b; i < e; ++i) {
                      if (!fitted[i]) continue;
                      const Eigen::Vector3d q = Eigen::Map<const Eigen::Vector3d>(points_I + 3 * i);
                      const Eigen::Vector3d nrm = Eigen::Map<const Eigen::Vector3d>(planes + 4 * i);
                      const double r = nrm.dot(R_WI * q + t_W) + planes[4 * i + 3];
                      if (!(std::abs(r) <= prm.max_residual)) continue;
                      const double w = robust_weight(prm.robust, r, prm.robust_scale);
                      const Eigen::Vector3d n_I = R_WI.transpose() * nrm;
                      Eigen::Matrix<double, 6, 1> J;
                      J.head<3>() = q.cross(n_I);
                      J.tail<3>() = n_I;
                      part.H.noalias() += (w * inv_s2) * J * J.transpose();
                      part.b.noalias() += (w * inv_s2 * r) * J;
                      part.cost += w * inv_s2 * r * r;
                      ++part.inliers;
                      out.valid[i] = 1;
                      out.residual[i] = r;
                      out.weight[i] = w;
                      for (int j = 0; j < 3; ++j) out.normal[3 * i + j] = nrm[j];
                    }
                  });
  for (const auto& part : parts) {
    out.H += part.H;
    out.b += part.b;
    out.cost += part.cost;
    out.inliers += part.inliers;
  }
  return out;
}

PlaneTerms VoxelMap::point_to_plane(const double* points_I, std::size_t n, const Eigen::Matrix3d& R_WI,
                                    const Eigen::Vector3d& t_W, const PlaneParams& prm, int threads) const {
  std::vector<std::uint8_t> fitted(n);
  std::vector<double> planes(4 * n);
  fit_planes(points_I, n, R_WI, t_W, prm, fitted.data(), planes.data(), threads);
  return plane_terms(points_I, planes.data(), fitted.data(), n, R_WI, t_W, prm, threads);
}

}  // namespace cufund::odometry
