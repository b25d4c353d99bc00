#include "deskew_crop.h"

#include <algorithm>
#include <cmath>

namespace cufund::perception {

void deskew_crop(const float* points_L, const double* dt, std::size_t n, std::size_t stride, const DeskewKnots& knots,
                 const CropBox& box, const std::int64_t* tall, std::size_t n_tall, CroppedScan& out) {
  out.points_W.clear();
  out.rays_W.clear();
  out.columns.clear();
  out.new_tall.clear();
  const std::size_t rows = n == 0 ? 0 : (n - 1) / stride + 1;
  out.points_W.reserve(3 * rows);
  out.rays_W.reserve(3 * rows);
  out.columns.reserve(rows);
  const auto K = static_cast<std::int64_t>(knots.segments);
  const double k_max = static_cast<double>(K);
  for (std::size_t r = 0; r < rows; ++r) {
    const std::size_t i = r * stride;
    const double x = std::clamp(dt[i] / knots.span * k_max, 0.0, k_max);
    const std::int64_t seg = std::min(static_cast<std::int64_t>(x), K - 1);
    const double s = x - static_cast<double>(seg);
    const double p[3] = {points_L[3 * i], points_L[3 * i + 1], points_L[3 * i + 2]};
    const double* Ra = knots.R_WL + 9 * seg;
    const double* Rb = Ra + 9;
    const double* ta = knots.p_WL + 3 * seg;
    const double* tb = ta + 3;
    double w[3], ray[3];
    for (int c = 0; c < 3; ++c) {
      const double a = p[0] * Ra[3 * c] + p[1] * Ra[3 * c + 1] + p[2] * Ra[3 * c + 2] + ta[c];
      const double b = p[0] * Rb[3 * c] + p[1] * Rb[3 * c + 1] + p[2] * Rb[3 * c + 2] + tb[c];
      w[c] = a + s * (b - a);
      ray[c] = w[c] - (ta[c] + s * (tb[c] - ta[c]));
    }
    const double range = std::sqrt(ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2]);
    if (!(range > 1e-6 && range <= box.max_range && w[2] <= box.z_max && w[2] >= box.z_min)) continue;
    constexpr std::int64_t kOff = std::int64_t{1} << 30;
    const auto ci = static_cast<std::int64_t>(std::floor(w[0] / box.column_cell)) + kOff;
    const auto cj = static_cast<std::int64_t>(std::floor(w[1] / box.column_cell)) + kOff;
    for (int c = 0; c < 3; ++c) {
      out.points_W.push_back(w[c]);
      out.rays_W.push_back(ray[c] / range);
    }
    const std::int64_t key = (ci << 31) | cj;
    out.columns.push_back(key);
    if (w[2] > box.tall_z && !std::binary_search(tall, tall + n_tall, key)) out.new_tall.push_back(key);
  }
  std::sort(out.new_tall.begin(), out.new_tall.end());
  out.new_tall.erase(std::unique(out.new_tall.begin(), out.new_tall.end()), out.new_tall.end());
  // Drop the points in tall columns, old or new (compacting in place, order kept).
  std::size_t kept = 0;
  for (std::size_t r = 0; r < out.columns.size(); ++r) {
    const std::int64_t key = out.columns[r];
    if (std::binary_search(tall, tall + n_tall, key) ||
        std::binary_search(out.new_tall.begin(), out.new_tall.end(), key)) {
      continue;
    }
    for (int c = 0; c < 3; ++c) {
      out.points_W[3 * kept + c] = out.points_W[3 * r + c];
      out.rays_W[3 * kept + c] = out.rays_W[3 * r + c];
    }
    out.columns[kept++] = key;
  }
  out.points_W.resize(3 * kept);
  out.rays_W.resize(3 * kept);
  out.columns.resize(kept);
}

}  // namespace cufund::perception
