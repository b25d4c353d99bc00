// cufund._core.render: the camera renderer (cpp/render) over the LiDAR's RaycastScene.
#include "render.h"
#include "pybind_common.h"

#include <string>

namespace cufund::py_bind {

namespace {

using lidar::RaycastScene;
using render::Texture;

constexpr py::ssize_t kMaterialColumns = 13;

template <typename T>
carray<T> shaped(const py::handle& obj, const char* field, std::initializer_list<py::ssize_t> shape) {
  auto a = contiguous<T>(obj, field);
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  py::ssize_t i = 0;
  std::string want = "(";
  for (py::ssize_t s : shape) {
    if (ok && s >= 0 && a.shape(i) != s) ok = false;
    want += (i ? ", " : "") + (s >= 0 ? std::to_string(s) : std::string("N"));
    ++i;
  }
  want += shape.size() == 1 ? ",)" : ")";
  if (!ok) throw py::value_error(std::string(field) + " must have shape " + want + ", got " + shape_str(a));
  return a;
}

py::dict render_image(const RaycastScene& scene, const py::handle& dirs_obj, const py::handle& row_p_obj,
                      const py::handle& row_R_obj, int width, int height, const py::handle& materials_obj,
                      const py::handle& tiles_obj, const py::handle& to_sun_obj, float ambient, bool shadows,
                      const py::handle& sky_obj, const py::handle& nthreads_obj) {
  if (width <= 0 || height <= 0) throw py::value_error("width and height must be > 0 [px]");
  const py::ssize_t n = static_cast<py::ssize_t>(width) * height;
  auto dirs = shaped<float>(dirs_obj, "dirs_O", {n, 3});
  auto row_p = shaped<double>(row_p_obj, "row_p", {height, 3});
  auto row_R = shaped<double>(row_R_obj, "row_R", {height, 3, 3});
  require_finite(row_p.data(), row_p.size(), "row_p");
  require_finite(row_R.data(), row_R.size(), "row_R");
  auto mats = shaped<double>(materials_obj, "materials", {-1, kMaterialColumns});
  auto tiles = contiguous<float>(tiles_obj, "tiles");
  if (tiles.ndim() != 3 || tiles.shape(1) != tiles.shape(2))
    throw py::value_error("tiles must have shape (T, S, S), got " + shape_str(tiles));
  auto to_sun = shaped<double>(to_sun_obj, "to_sun", {3});
  auto sky = shaped<double>(sky_obj, "sky", {3});
  const int nthreads = threads_arg(nthreads_obj);

  std::vector<render::SurfaceMaterial> table(static_cast<std::size_t>(mats.shape(0)));
  for (std::size_t g = 0; g < table.size(); ++g) {
    const double* r = mats.data() + kMaterialColumns * g;
    const int tex = static_cast<int>(r[0]);
    if (tex < 0 || tex > static_cast<int>(Texture::kExternal) || !std::isfinite(r[7]) || r[7] <= 0.0)
      throw py::value_error("materials[" + std::to_string(g) + "]: texture code must be in [0, 6] and scale > 0");
    auto& m = table[g];
    m.texture = static_cast<Texture>(tex);
    for (int i = 0; i < 3; ++i) {
      m.albedo[i] = static_cast<float>(r[1 + i]);
      m.dark[i] = static_cast<float>(r[4 + i]);
    }
    m.scale = static_cast<float>(r[7]);
    m.seed = static_cast<std::uint32_t>(r[8]);
    m.tile = static_cast<std::int32_t>(r[9]);
    m.offset[0] = static_cast<float>(r[10]);
    m.offset[1] = static_cast<float>(r[11]);
    if (m.tile >= tiles.shape(0) || (m.tile < 0 && m.texture != Texture::kNone && m.texture != Texture::kChecker &&
                                     m.texture != Texture::kExternal))
      throw py::value_error("materials[" + std::to_string(g) + "]: a noise-based texture needs a tile index < " +
                            std::to_string(tiles.shape(0)));
  }
  render::Lighting light;
  for (int i = 0; i < 3; ++i) {
    light.to_sun[i] = static_cast<float>(to_sun.data()[i]);
    light.sky[i] = static_cast<float>(sky.data()[i]);
  }
  light.ambient = ambient;
  light.shadows = shadows;
  render::View view{dirs.data(), width, height, row_p.data(), row_R.data()};
  py::array_t<float> rgb({n, static_cast<py::ssize_t>(3)});
  py::array_t<std::int32_t> ids(n);
  py::array_t<float> shade(n);
  render::Frame frame{rgb.mutable_data(), ids.mutable_data(), shade.mutable_data()};
  render::Tiles tl{tiles.data(), static_cast<int>(tiles.shape(0)), static_cast<int>(tiles.shape(1))};
  render::RenderResult r;
  {
    py::gil_scoped_release release;
    r = render::render(scene, view, table.data(), table.size(), tl, light, frame, nthreads);
  }
  if (r.status == render::RenderStatus::kBadMaterial)
    throw py::value_error("materials has no row for geometry id " + std::to_string(r.index));
  if (r.status != render::RenderStatus::kOk)
    throw py::value_error("bad view: ray " + std::to_string(r.index) + " is not finite or has a zero direction");
  py::dict d;
  d["rgb"] = rgb;
  d["ids"] = ids;
  d["shade"] = shade;
  return d;
}

py::array_t<double> pattern(int texture, const py::handle& a_obj, const py::handle& b_obj, const py::handle& tile_obj,
                            std::uint32_t seed) {
  if (texture < 0 || texture > static_cast<int>(Texture::kExternal))
    throw py::value_error("texture code must be in [0, 6], got " + std::to_string(texture));
  auto a = contiguous<double>(a_obj, "a");
  auto b = contiguous<double>(b_obj, "b");
  if (a.ndim() != 1 || b.ndim() != 1 || a.shape(0) != b.shape(0))
    throw py::value_error("a and b must be 1-D arrays of one length, got " + shape_str(a) + " and " + shape_str(b));
  auto tile = contiguous<float>(tile_obj, "tile");
  if (tile.ndim() != 2 || tile.shape(0) != tile.shape(1) || tile.shape(0) < 1)
    throw py::value_error("tile must be a square (S, S) array, got " + shape_str(tile));
  py::array_t<double> out(a.shape(0));
  const auto t = static_cast<Texture>(texture);
  const int s = static_cast<int>(tile.shape(0));
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    out.mutable_data()[i] = render::pattern(t, a.data()[i], b.data()[i], tile.data(), s, seed);
  return out;
}

}  // namespace

void define_render(py::module_& m) {
  m.def("render_image", &render_image, py::arg("scene"), py::arg("dirs_O"), py::arg("row_p"), py::arg("row_R"),
        py::arg("width"), py::arg("height"), py::arg("materials"), py::arg("tiles"), py::arg("to_sun"),
        py::arg("ambient"), py::arg("shadows"), py::arg("sky"), py::arg("nthreads") = 0, R"doc(
Renders one camera image of a RaycastScene: pixel k looks along ``dirs_O[k]`` (optical frame, (H*W, 3) float32)
from row r's pose ``row_p[r]`` (p_WO, (H, 3)) and ``row_R[r]`` (R_WO, (H, 3, 3)). ``materials`` (G, 13) float64,
one row per geometry id: texture code, albedo (3), dark colour (3), scale [m], seed, tile index, offset (2), unused.
``tiles`` (T, S, S) float32 noise tiles. Lambert shading: ambient + (1 - ambient) max(0, n.l) with one shadow ray
per lit pixel when ``shadows`` (else |n.l| without rays). Releases the GIL; packets of 8 coherent rays; the shared
thread pool. Returns {rgb (H*W, 3) float32 linear, ids (H*W,) int32 (-1: sky), shade (H*W,) float32}.)doc");
  m.def("pattern", &pattern, py::arg("texture"), py::arg("a"), py::arg("b"), py::arg("tile"), py::arg("seed"),
        "The procedural pattern (cpp/render/textures.h) at plane coordinates (a, b) [scale units].");
}

}  // namespace cufund::py_bind
