#include "batch_cast.h"

#include "rotation.h"
#include "thread_pool.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace cufund::lidar {

namespace {

constexpr double kInfD = std::numeric_limits<double>::infinity();

bool finite_n(const double* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) return false;
  return true;
}

bool zero_quaternion(const double* q) { return q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 0; }

// The rays of sensor i: rows (p_WS, R_WS d_S[r]) in float32.
void sensor_rays(const SensorPoses& poses, std::size_t i, const float* d_S, std::size_t r, float* rays) {
  double R[9];
  quat_to_rotation(poses.q_WS + 4 * i, R);
  const double* p = poses.p_WS + 3 * i;
  const float o[3] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
  for (std::size_t k = 0; k < r; ++k) {
    const double dx = d_S[3 * k], dy = d_S[3 * k + 1], dz = d_S[3 * k + 2];
    float* row = rays + 6 * k;
    row[0] = o[0];
    row[1] = o[1];
    row[2] = o[2];
    row[3] = static_cast<float>(R[0] * dx + R[1] * dy + R[2] * dz);
    row[4] = static_cast<float>(R[3] * dx + R[4] * dy + R[5] * dz);
    row[5] = static_cast<float>(R[6] * dx + R[7] * dy + R[8] * dz);
  }
}

// SplitMix64 (Steele, Lea, Flood 2014): a stream per (seed + vehicle, frame), independent of threads.
struct SplitMix64 {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in (0, 1): 53 random bits, never 0 (Box-Muller takes its log).
  double uniform() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }
};

std::uint64_t stream_key(std::uint64_t seed, std::uint64_t frame) {
  SplitMix64 a{seed};
  SplitMix64 b{a.next() ^ frame};
  return b.next();
}

BatchResult check_poses(const SensorPoses& poses) {
  for (std::size_t i = 0; i < poses.n; ++i) {
    if (!finite_n(poses.p_WS + 3 * i, 3) || !finite_n(poses.q_WS + 4 * i, 4)) {
      return {BatchStatus::kNonFinitePose, i};
    }
    if (zero_quaternion(poses.q_WS + 4 * i)) return {BatchStatus::kZeroQuaternion, i};
  }
  return {};
}

BatchResult check_directions(const float* d_S, std::size_t r) {
  for (std::size_t k = 0; k < r; ++k) {
    const float* d = d_S + 3 * k;
    if (!(std::isfinite(d[0]) && std::isfinite(d[1]) && std::isfinite(d[2]))) {
      return {BatchStatus::kNonFiniteDirection, k};
    }
    if (d[0] == 0.0f && d[1] == 0.0f && d[2] == 0.0f) return {BatchStatus::kZeroDirection, k};
  }
  return {};
}

BatchResult check_boxes(const VehicleBoxes& boxes, std::size_t n) {
  for (std::size_t j = 0; j < boxes.m; ++j) {
    const double* h = boxes.half_extents + 3 * j;
    if (!finite_n(boxes.p_WB + 3 * j, 3) || !finite_n(boxes.q_WB + 4 * j, 4) || !finite_n(h, 3) ||
        zero_quaternion(boxes.q_WB + 4 * j) || h[0] < 0 || h[1] < 0 || h[2] < 0) {
      return {BatchStatus::kBadBox, j};
    }
  }
  if (boxes.m > 0 && boxes.owner) {
    for (std::size_t i = 0; i < n; ++i) {
      if (boxes.owner[i] < -1 || boxes.owner[i] >= static_cast<std::int64_t>(boxes.m)) {
        return {BatchStatus::kBadOwner, i};
      }
    }
  }
  return {};
}

// A box in the frame of one sensor's rays: origin and rotation into the box's frame.
struct BoxView {
  double o_B[3];
  double Rt[9];  // R_WB^T, row-major
  double h[3];
};

// Slab test of the ray o_B + t d_B against [-h, h]: entry distance (0 inside), +inf on a miss.
double slab(const double o[3], const double d[3], const double h[3]) {
  double t0 = 0.0, t1 = kInfD;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < -h[a] || o[a] > h[a]) return kInfD;
      continue;
    }
    const double inv = 1.0 / d[a];
    double ta = (-h[a] - o[a]) * inv, tb = (h[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return kInfD;
  }
  return t0;
}

}  // namespace

double ray_box_distance(const double o[3], const double d[3], const double c[3], const double q[4], const double h[3]) {
  double R[9];
  quat_to_rotation(q, R);
  const double v[3] = {o[0] - c[0], o[1] - c[1], o[2] - c[2]};
  double o_B[3], d_B[3];
  for (int a = 0; a < 3; ++a) {
    o_B[a] = R[a] * v[0] + R[3 + a] * v[1] + R[6 + a] * v[2];
    d_B[a] = R[a] * d[0] + R[3 + a] * d[1] + R[6 + a] * d[2];
  }
  return slab(o_B, d_B, h);
}

BatchResult batch_rays(const SensorPoses& poses, const float* d_S, std::size_t r, float* rays, int nthreads) {
  BatchResult res = check_poses(poses);
  if (res.status == BatchStatus::kOk) res = check_directions(d_S, r);
  if (res.status != BatchStatus::kOk) return res;
  parallel_chunks(static_cast<std::ptrdiff_t>(poses.n), 1, nthreads,
                  [&](std::size_t i, std::size_t, std::size_t) { sensor_rays(poses, i, d_S, r, rays + 6 * r * i); });
  return {};
}

BatchResult batch_cast(const RaycastScene& scene, const SensorPoses& poses, const float* d_S, std::size_t r,
                       const VehicleBoxes& boxes, const BatchRangeModel& model, float* out, int nthreads) {
  BatchResult res = check_poses(poses);
  if (res.status == BatchStatus::kOk) res = check_directions(d_S, r);
  if (res.status == BatchStatus::kOk) res = check_boxes(boxes, poses.n);
  if (res.status != BatchStatus::kOk) return res;
  ForkSafeSection no_fork;
  parallel_chunks(static_cast<std::ptrdiff_t>(poses.n), 1, nthreads, [&](std::size_t i, std::size_t, std::size_t) {
    thread_local std::vector<float> rays;
    if (rays.size() < 6 * r) rays.resize(6 * r);
    sensor_rays(poses, i, d_S, r, rays.data());
    float* t = out + r * i;
    // Inside a pool chunk this runs on this thread alone: the packets and hits of cast_rays(kCoherent).
    scene.cast_rays(rays.data(), r, RayHits{t}, 1, RayOrder::kCoherent);
    if (boxes.m > 0) {
      const double* p = poses.p_WS + 3 * i;
      const std::int64_t own = boxes.owner ? boxes.owner[i] : -1;
      thread_local std::vector<BoxView> views;  // reused: no allocation per vehicle and call
      views.clear();
      for (std::size_t j = 0; j < boxes.m; ++j) {
        if (static_cast<std::int64_t>(j) == own) continue;
        const double* c = boxes.p_WB + 3 * j;
        const double* h = boxes.half_extents + 3 * j;
        const double v[3] = {static_cast<double>(static_cast<float>(p[0])) - c[0],
                             static_cast<double>(static_cast<float>(p[1])) - c[1],
                             static_cast<double>(static_cast<float>(p[2])) - c[2]};
        // Rays report nothing past range_max: a box entirely beyond it (in |d| >= 1 units) is skipped.
        const double reach =
            std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        if (reach > static_cast<double>(model.range_max)) continue;
        BoxView b;
        double R[9];
        quat_to_rotation(boxes.q_WB + 4 * j, R);
        for (int a = 0; a < 3; ++a) {
          for (int k = 0; k < 3; ++k) b.Rt[3 * a + k] = R[3 * k + a];
          b.o_B[a] = R[a] * v[0] + R[3 + a] * v[1] + R[6 + a] * v[2];
          b.h[a] = h[a];
        }
        views.push_back(b);
      }
      for (const BoxView& b : views) {
        for (std::size_t k = 0; k < r; ++k) {
          const float* d = rays.data() + 6 * k + 3;
          double d_B[3];
          for (int a = 0; a < 3; ++a) d_B[a] = b.Rt[3 * a] * d[0] + b.Rt[3 * a + 1] * d[1] + b.Rt[3 * a + 2] * d[2];
          const double tb = slab(b.o_B, d_B, b.h);
          if (tb < static_cast<double>(t[k])) t[k] = static_cast<float>(tb);
        }
      }
    }
    apply_range_model(model, i, t, r);
  });
  return {};
}

void apply_range_model(const BatchRangeModel& model, std::size_t i, float* t, std::size_t r) {
  const bool noisy = model.noise_std > 0 || model.noise_per_m > 0;
  const bool drops = model.dropout > 0;
  SplitMix64 rng{stream_key(model.seed + i, model.frame)};
  for (std::size_t k = 0; k < r; ++k) {
    float v = t[k];
    bool valid = v >= model.range_min && v <= model.range_max;
    // Draws for every ray, hit or not: a frame's draws do not depend on the scene.
    if (drops && rng.uniform() < model.dropout) valid = false;
    if (noisy) {
      const double u1 = rng.uniform(), u2 = rng.uniform();
      const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
      if (valid) v = static_cast<float>(std::max(0.0, v + (model.noise_std + model.noise_per_m * v) * z));
    }
    t[k] = valid ? v : model.miss_value;
  }
}

BatchResult check_sensor_input(const SensorPoses& poses, const float* d_S, std::size_t r) {
  BatchResult res = check_poses(poses);
  if (res.status == BatchStatus::kOk) res = check_directions(d_S, r);
  return res;
}

}  // namespace cufund::lidar
