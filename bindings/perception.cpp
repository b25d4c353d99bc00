// Bindings of cpp/perception: the tunnel detector's kernels (cufund.perception.detection and
// cufund.perception.tunnel_detector): DBSCAN labels, a scan deskewed and cropped, RANSAC line support.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "dbscan.h"
#include "deskew_crop.h"
#include "line_support.h"
#include "pybind_common.h"

namespace cufund::py_bind {

void define_perception(py::module_& m) {
  m.def(
      "dbscan",
      [](const py::handle& points, const py::handle& eps_obj, const py::handle& min_points_obj) {
        py::array arr = checked_array(points, "points");
        if (arr.ndim() != 2 || arr.shape(1) != 3) {
          throw py::value_error("points must have shape (N, 3), got " + shape_str(arr));
        }
        const py::ssize_t n = arr.shape(0);
        auto p = as_float64(points, "points", {n, 3});
        require_finite(p.data(), 3 * n, "points");
        const double eps = finite_arg(eps_obj, "eps");
        if (!(eps > 0)) throw py::value_error("eps must be > 0 [m], got " + std::to_string(eps));
        const auto min_points = static_cast<std::size_t>(int_arg(min_points_obj, "min_points", 1, 1 << 30));
        if (n >= (py::ssize_t{1} << 31)) throw py::value_error("points must hold fewer than 2^31 rows");
        py::array_t<std::int64_t> labels(n);
        {
          py::gil_scoped_release release;
          perception::dbscan(p.data(), static_cast<std::size_t>(n), eps, min_points, labels.mutable_data());
        }
        return labels;
      },
      py::arg("points"), py::arg("eps"), py::arg("min_points"), R"doc(
DBSCAN cluster labels (N,) int64 of ``points`` (N, 3), as Open3D's PointCloud.cluster_dbscan(eps,
min_points) labels them: core points have >= min_points points (themselves included) closer than eps [m];
clusters numbered 0, 1, ... by their lowest-index core point; a border point takes the lowest-numbered
cluster near it; noise is -1.
)doc");

  m.def(
      "deskew_crop",
      [](const py::handle& points_L, const py::handle& dt, const py::handle& stride_obj, const py::handle& span_obj,
         const py::handle& p_WL, const py::handle& R_WL, const py::handle& max_range, const py::handle& z_min,
         const py::handle& z_max, const py::handle& tall_z, const py::handle& column_cell, const py::handle& tall_obj) {
        py::array arr = checked_array(points_L, "points_L");
        if (arr.ndim() != 2 || arr.shape(1) != 3) {
          throw py::value_error("points_L must have shape (N, 3), got " + shape_str(arr));
        }
        const py::ssize_t n = arr.shape(0);
        auto pts = contiguous<float>(arr, "points_L");
        auto times = as_float64(dt, "dt", {n});
        require_finite(times.data(), n, "dt");
        for (py::ssize_t i = 0; i < 3 * n; ++i) {
          if (!std::isfinite(pts.data()[i])) throw py::value_error("points_L must be finite, got a NaN or inf");
        }
        const auto stride = static_cast<std::size_t>(int_arg(stride_obj, "stride", 1, 1 << 30));
        perception::DeskewKnots knots;
        knots.span = finite_arg(span_obj, "span");
        if (!(knots.span > 0)) throw py::value_error("span must be > 0 [s]");
        py::array k_arr = checked_array(p_WL, "p_WL");
        if (k_arr.ndim() != 2 || k_arr.shape(0) < 2) {
          throw py::value_error("p_WL must have shape (K + 1, 3) with K >= 1, got " + shape_str(k_arr));
        }
        const py::ssize_t k = k_arr.shape(0);
        auto p = as_float64(p_WL, "p_WL", {k, 3});
        auto R = as_float64(R_WL, "R_WL", {k, 3, 3});
        require_finite(p.data(), 3 * k, "p_WL");
        require_finite(R.data(), 9 * k, "R_WL");
        knots.segments = static_cast<std::size_t>(k - 1);
        knots.p_WL = p.data();
        knots.R_WL = R.data();
        perception::CropBox box{finite_arg(max_range, "max_range"), finite_arg(z_min, "z_min"),
                                finite_arg(z_max, "z_max"), finite_arg(tall_z, "tall_z"),
                                finite_arg(column_cell, "column_cell")};
        if (!(box.column_cell > 0)) throw py::value_error("column_cell must be > 0 [m]");
        py::array t_arr = checked_array(tall_obj, "tall");
        if (t_arr.ndim() != 1 || t_arr.dtype().kind() != 'i') {
          throw py::value_error("tall must be a sorted (T,) integer array of column keys, got " +
                                std::string(py::str(t_arr.dtype())) + " " + shape_str(t_arr));
        }
        auto tall = contiguous<std::int64_t>(t_arr, "tall");
        for (py::ssize_t i = 0; i + 1 < tall.shape(0); ++i) {
          if (tall.data()[i + 1] < tall.data()[i]) throw py::value_error("tall must be sorted ascending");
        }
        thread_local perception::CroppedScan out;
        {
          py::gil_scoped_release release;
          perception::deskew_crop(pts.data(), times.data(), static_cast<std::size_t>(n), stride, knots, box,
                                  tall.data(), static_cast<std::size_t>(tall.shape(0)), out);
        }
        const auto m = static_cast<py::ssize_t>(out.columns.size());
        py::array_t<double> points_W({m, py::ssize_t{3}}), rays_W({m, py::ssize_t{3}});
        py::array_t<std::int64_t> new_tall(static_cast<py::ssize_t>(out.new_tall.size()));
        std::copy(out.points_W.begin(), out.points_W.end(), points_W.mutable_data());
        std::copy(out.rays_W.begin(), out.rays_W.end(), rays_W.mutable_data());
        std::copy(out.new_tall.begin(), out.new_tall.end(), new_tall.mutable_data());
        return py::make_tuple(points_W, rays_W, new_tall);
      },
      py::arg("points_L"), py::arg("dt"), py::arg("stride"), py::arg("span"), py::arg("p_WL"), py::arg("R_WL"),
      py::arg("max_range"), py::arg("z_min"), py::arg("z_max"), py::arg("tall_z"), py::arg("column_cell"),
      py::arg("tall"), R"doc(
A scan moved to the world point by point and cropped (the tunnel detector's input). Rows 0, stride, ...
of ``points_L`` (N, 3) [m] fired at ``dt`` (N,) [s] from the scan start; K + 1 sensor poses ``p_WL``
(K + 1, 3) [m], ``R_WL`` (K + 1, 3, 3) evenly over [0, span] [s]: a point is moved with the two poses
around its time and the results blended linearly. Keeps the points 1e-6 m to max_range [m] from the
sensor with z in [z_min, z_max] [m], in order, except those in tall x-y columns (keys as
detection.column_keys, edge column_cell [m]): the sorted int64 keys ``tall``, and the columns where a kept
point of this scan lies above tall_z [m]. Returns (points_W (M, 3), unit rays_W (M, 3) from the sensor,
new_tall: the sorted keys of those new tall columns not in ``tall``).
)doc");

  m.def(
      "line_support",
      [](const py::handle& along_obj, const py::handle& inlier_obj) {
        py::array a_arr = checked_array(along_obj, "along");
        if (a_arr.ndim() != 2) throw py::value_error("along must have shape (N, K), got " + shape_str(a_arr));
        if (a_arr.dtype().kind() != 'i') {
          throw py::value_error("along must have an integer dtype, got " + std::string(py::str(a_arr.dtype())));
        }
        py::array i_arr = checked_array(inlier_obj, "inlier");
        if (i_arr.dtype().kind() != 'b' || i_arr.ndim() != 2 || i_arr.shape(0) != a_arr.shape(0) ||
            i_arr.shape(1) != a_arr.shape(1)) {
          throw py::value_error("inlier must be a bool array shaped like along " + shape_str(a_arr) + ", got " +
                                std::string(py::str(i_arr.dtype())) + " " + shape_str(i_arr));
        }
        auto along = contiguous<std::int64_t>(a_arr, "along");
        auto inlier = contiguous<bool>(i_arr, "inlier");
        const py::ssize_t n = a_arr.shape(0), k = a_arr.shape(1);
        py::array_t<std::int64_t> covered(k), counts(k);
        {
          py::gil_scoped_release release;
          perception::line_support(along.data(), inlier.data(), static_cast<std::size_t>(n),
                                   static_cast<std::size_t>(k), covered.mutable_data(), counts.mutable_data());
        }
        return py::make_tuple(covered, counts);
      },
      py::arg("along"), py::arg("inlier"), R"doc(
Support of K candidate lines over N points: ``along`` (N, K) integer bin of each point along each line,
``inlier`` (N, K) bool. Returns (covered (K,), counts (K,)) int64: the distinct bins among each line's
inliers, and its inliers.
)doc");
}

}  // namespace cufund::py_bind
