// An exact analytic depth caster for scenes of vertical convex prisms and horizontal rectangles (the forest:
// capped n-gon trunks on a ground quad), for N pinhole cameras in one call. It reports what the Embree
// RaycastScene of the same meshes reports (a convex prism's faces bound the intersection of its half-spaces, so
// the first face a ray meets is where it enters that intersection: Cyrus-Beck clipping), within float rounding;
// only rays grazing an edge may differ in hit or miss.
//
// Per camera: the rays are rotated once into column-major SoA float arrays; each rectangle is tested against
// every ray; each prism is culled by distance (range_max) and by its bounding box's projection into the image
// (a pinhole maps a convex box in front of it to a convex region bounded by its corners' images), then clipped
// against the rays of the columns and rows it can cover, each plane one loop over a column's rows (auto-
// vectorised: no branches, float selects). Threads run over cameras. The range model (range_min/max, noise,
// dropout, their seeded streams) is lidar::apply_range_model's, as in lidar::batch_cast.
#pragma once

#include <cstddef>
#include <vector>

#include "batch_cast.h"

namespace cufund::envs {

struct PrismScene {
  // Prism j is {(x, y, z): nx[k] x + ny[k] y <= c[k] for k in [plane_begin[j], plane_begin[j + 1]),
  // zmin[j] <= z <= zmax[j]}; box_* its axis-aligned bounds (culling only).
  std::vector<float> nx, ny;
  std::vector<double> c;
  std::vector<std::size_t> plane_begin{0};
  std::vector<double> zmin, zmax, box_x0, box_x1, box_y0, box_y1;
  // Rectangle j: z = rect_z[j], rect_x0[j] <= x <= rect_x1[j], rect_y0[j] <= y <= rect_y1[j] (seen from both sides).
  std::vector<double> rect_z, rect_x0, rect_x1, rect_y0, rect_y1;

  std::size_t prisms() const { return zmin.size(); }
  std::size_t rects() const { return rect_z.size(); }
};

enum class PrismSceneStatus { kOk, kBadPrism, kBadRect };
struct PrismSceneCheck {
  PrismSceneStatus status = PrismSceneStatus::kOk;
  std::size_t index = 0;
};
// Finite numbers, a non-degenerate plane normal, plane_begin increasing from 0 to nx.size(), zmin <= zmax, x0 <= x1...
PrismSceneCheck check_scene(const PrismScene& scene);

// The pinhole camera whose rays d_S (width * height, 3) are, row-major, (1, -x_n, -y_n) with
// x_n = (u + 0.5 - width / 2) / focal, y_n = (v + 0.5 - height / 2) / focal (DepthCameraSpec.directions()).
struct Pinhole {
  int width = 0;
  int height = 0;
  double focal = 0.0;  // [px]
};

// The first of d_S's width * height rays that is not cam's (1, -x_n, -y_n) within float rounding (the float32
// DepthCameraSpec.directions() rounds), or width * height when all are. prism_depth_cast culls each prism by the
// pixels cam maps it to, so its d_S must pass this check (the binding refuses others).
std::size_t first_non_pinhole_ray(const float* d_S, const Pinhole& cam);

// Writes out (N, height * width) float32 depths (distance along each d_S ray) per the range model, as
// lidar::batch_cast(RaycastScene of the scene's meshes, poses, d_S, no boxes, model) does. The input is checked
// first (poses, directions); nothing is written on bad input. nthreads <= 0: every core.
lidar::BatchResult prism_depth_cast(const PrismScene& scene, const lidar::SensorPoses& poses, const float* d_S,
                                    const Pinhole& cam, const lidar::BatchRangeModel& model, float* out,
                                    int nthreads = 0);

}  // namespace cufund::envs
