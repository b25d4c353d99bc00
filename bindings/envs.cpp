// cufund._core.envs: the learning environments' batch (cpp/envs), stepped with the GIL released.
#include <array>
#include <stdexcept>

#include "env_batch.h"
#include "prism_cast.h"
#include "pybind_common.h"
#include "range_model_args.h"

namespace cufund::py_bind {

using envs::check_scene;
using envs::Pinhole;
using envs::prism_depth_cast;
using envs::PrismScene;
using envs::PrismSceneCheck;
using envs::PrismSceneStatus;

// The analytic depth caster (prism_cast.h): vertical convex prisms and horizontal rectangles.
void define_prism_cast(py::module_& m) {
  py::class_<PrismScene>(
      m, "PrismScene", "Vertical convex prisms and horizontal rectangles for prism_depth_cast (cpp/envs/prism_cast.h).")
      .def(py::init([](const py::handle& planes_obj, const py::handle& begin_obj, const py::handle& prisms_obj,
                       const py::handle& rects_obj) {
             py::array pa = checked_array(planes_obj, "planes");
             if (pa.ndim() != 2 || pa.shape(1) != 3)
               throw py::value_error("planes must have shape (K, 3), got " + shape_str(pa));
             auto planes = as_float64(planes_obj, "planes", {pa.shape(0), 3});
             py::array pr = checked_array(prisms_obj, "prisms");
             if (pr.ndim() != 2 || pr.shape(1) != 6)
               throw py::value_error("prisms must have shape (P, 6), got " + shape_str(pr));
             const py::ssize_t n = pr.shape(0);
             auto prisms = as_float64(prisms_obj, "prisms", {n, 6});
             py::array ba = checked_array(begin_obj, "plane_begin");
             if (ba.dtype().kind() != 'i' && ba.dtype().kind() != 'u') {
               throw py::value_error("plane_begin must have an integer dtype, got " + std::string(py::str(ba.dtype())));
             }
             if (ba.ndim() != 1 || ba.shape(0) != n + 1) {
               throw py::value_error("plane_begin must have shape (" + std::to_string(n + 1) + ",), got " +
                                     shape_str(ba));
             }
             auto begin = contiguous<std::int64_t>(ba, "plane_begin");
             py::array ra = checked_array(rects_obj, "rects");
             if (ra.ndim() != 2 || ra.shape(1) != 5)
               throw py::value_error("rects must have shape (M, 5), got " + shape_str(ra));
             auto rects = as_float64(rects_obj, "rects", {ra.shape(0), 5});
             PrismScene s;
             s.plane_begin.clear();
             for (py::ssize_t j = 0; j <= n; ++j) {
               if (begin.data()[j] < 0) throw py::value_error("plane_begin must be >= 0");
               s.plane_begin.push_back(static_cast<std::size_t>(begin.data()[j]));
             }
             for (py::ssize_t k = 0; k < pa.shape(0); ++k) {
               s.nx.push_back(static_cast<float>(planes.data()[3 * k]));
               s.ny.push_back(static_cast<float>(planes.data()[3 * k + 1]));
               s.c.push_back(planes.data()[3 * k + 2]);
             }
             for (py::ssize_t j = 0; j < n; ++j) {
               const double* v = prisms.data() + 6 * j;
               s.zmin.push_back(v[0]), s.zmax.push_back(v[1]), s.box_x0.push_back(v[2]), s.box_x1.push_back(v[3]);
               s.box_y0.push_back(v[4]), s.box_y1.push_back(v[5]);
             }
             for (py::ssize_t j = 0; j < ra.shape(0); ++j) {
               const double* v = rects.data() + 5 * j;
               s.rect_z.push_back(v[0]), s.rect_x0.push_back(v[1]), s.rect_x1.push_back(v[2]);
               s.rect_y0.push_back(v[3]), s.rect_y1.push_back(v[4]);
             }
             const PrismSceneCheck c = check_scene(s);
             if (c.status == PrismSceneStatus::kBadPrism) {
               throw py::value_error("prism " + std::to_string(c.index) +
                                     ": planes (nx, ny, c) must be finite with (nx, ny) != 0, plane_begin increasing "
                                     "from 0 to K, and (zmin, zmax, x0, x1, y0, y1) finite with min <= max");
             }
             if (c.status == PrismSceneStatus::kBadRect) {
               throw py::value_error("rect " + std::to_string(c.index) +
                                     ": (z, x0, x1, y0, y1) must be finite with x0 <= x1 and y0 <= y1");
             }
             return s;
           }),
           py::arg("planes"), py::arg("plane_begin"), py::arg("prisms"), py::arg("rects"),
           "planes (K, 3) (nx, ny, c): inside nx x + ny y <= c; prism j's planes plane_begin[j]:plane_begin[j + 1]; "
           "prisms (P, 6) (zmin, zmax, x0, x1, y0, y1: its z extent and xy bounding box) [m]; rects (M, 5) "
           "(z, x0, x1, y0, y1) [m].")
      .def_property_readonly("num_prisms", &PrismScene::prisms)
      .def_property_readonly("num_rects", &PrismScene::rects);
  m.def(
      "prism_depth_cast",
      [](const PrismScene& scene, const py::handle& d_S_obj, const py::handle& p_obj, const py::handle& q_obj,
         int width, int height, double focal, const py::handle& range_min, const py::handle& range_max,
         const py::handle& miss_value, const py::handle& noise_std, const py::handle& noise_per_m,
         const py::handle& dropout, const py::handle& seed, const py::handle& frame, const py::handle& nthreads_obj) {
        const int nthreads = threads_arg(nthreads_obj);
        if (width < 1 || height < 1) throw py::value_error("width and height must be >= 1");
        if (!(std::isfinite(focal) && focal > 0)) throw py::value_error("focal must be a finite number > 0 [px]");
        const py::ssize_t r = static_cast<py::ssize_t>(width) * height;
        py::array da = checked_array(d_S_obj, "d_S");
        if (da.dtype().kind() != 'f' && da.dtype().kind() != 'i' && da.dtype().kind() != 'u') {
          throw py::value_error("d_S must have a real numeric dtype (float32 preferred), got " +
                                std::string(py::str(da.dtype())));
        }
        auto d = contiguous<float>(da, "d_S");
        if (d.ndim() != 2 || d.shape(0) != r || d.shape(1) != 3) {
          throw py::value_error("d_S must have shape " + expected_shape_str({r, 3}) + ", got " + shape_str(d));
        }
        // The caster culls by the pixels (width, height, focal) map a prism to: rays of another camera would be
        // cast against the wrong prisms.
        const std::size_t bad = envs::first_non_pinhole_ray(d.data(), {width, height, focal});
        if (bad != static_cast<std::size_t>(r)) {
          throw py::value_error("d_S must be the rays (1, -x_n, -y_n) of the " + std::to_string(width) + " x " +
                                std::to_string(height) + " pinhole of focal " + std::to_string(focal) +
                                " px (DepthCameraSpec.directions()): ray " + std::to_string(bad) + " is not");
        }
        py::array pa = checked_array(p_obj, "p_WS");
        if (pa.ndim() != 2 || pa.shape(1) != 3)
          throw py::value_error("p_WS must have shape (N, 3), got " + shape_str(pa));
        const py::ssize_t n = pa.shape(0);
        auto p = as_float64(p_obj, "p_WS", {n, 3});
        auto q = as_float64(q_obj, "q_WS", {n, 4});
        const lidar::BatchRangeModel model =
            batch_range_model_arg({range_min, range_max, miss_value, noise_std, noise_per_m, dropout, seed, frame});
        py::array_t<float> out({n, r});
        lidar::BatchResult res;
        {
          py::gil_scoped_release release;
          res = prism_depth_cast(scene, {p.data(), q.data(), static_cast<std::size_t>(n)}, d.data(),
                                 {width, height, focal}, model, out.mutable_data(), nthreads);
        }
        if (res.status != lidar::BatchStatus::kOk) {
          throw py::value_error("p_WS, q_WS (finite, q non-zero) and d_S (finite, non-zero) checked: item " +
                                std::to_string(res.index) + " is not");
        }
        return out;
      },
      py::arg("scene"), py::arg("d_S"), py::arg("p_WS"), py::arg("q_WS"), py::kw_only(), py::arg("width"),
      py::arg("height"), py::arg("focal"), py::arg("range_min") = 0.0,
      py::arg("range_max") = std::numeric_limits<double>::infinity(),
      py::arg("miss_value") = std::numeric_limits<double>::infinity(), py::arg("noise_std") = 0.0,
      py::arg("noise_per_m") = 0.0, py::arg("dropout") = 0.0, py::arg("seed") = 0, py::arg("frame") = 0,
      py::arg("nthreads") = 0,
      "(N, width * height) float32 depths of N pinhole cameras (d_S the camera's rays, DepthCameraSpec.directions()) "
      "in a PrismScene, GIL released: what cufund._core.lidar.batch_cast returns for the scene's meshes (no boxes), "
      "within float rounding, with the same range model and noise streams.");
}

void define_envs(py::module_& m) {
  define_prism_cast(m);
  m.def(
      "velocity_command",
      [](const std::array<double, 4>& a, const std::array<double, 3>& v_W, const std::array<double, 4>& q_WB,
         double mass, double gravity, double max_thrust, double max_speed, double max_rate, double velocity_gain,
         double attitude_gain) {
        double thrust = 0.0;
        Eigen::Vector3d w_sp;
        velocity_command({mass, gravity, max_thrust, max_speed, max_rate, velocity_gain, attitude_gain}, a.data(),
                         v_W.data(), q_WB.data(), &thrust, &w_sp);
        return py::make_tuple(thrust, w_sp);
      },
      py::arg("a"), py::arg("v_W"), py::arg("q_WB"), py::arg("mass"), py::arg("gravity"), py::arg("max_thrust"),
      py::arg("max_speed"), py::arg("max_rate"), py::arg("velocity_gain"), py::arg("attitude_gain"),
      "The velocity action mode's (collective thrust [N], body-rate setpoint [rad/s] (3,)) for action a (4,): the "
      "envs' formula, shared by the policy controller.");
  py::class_<EnvTaskParams>(m, "EnvTaskParams", "A task as cpp/envs reads it (built by cufund.envs from TaskConfig).")
      .def(py::init<>())
      .def_property(
          "task", [](const EnvTaskParams& t) { return static_cast<int>(t.task); },
          [](EnvTaskParams& t, int v) {
            if (v < 0 || v > 2) throw py::value_error("task must be 0 (hover), 1 (waypoints) or 2 (gates)");
            t.task = static_cast<EnvTask>(v);
          })
      .def_property(
          "action_mode", [](const EnvTaskParams& t) { return static_cast<int>(t.action_mode); },
          [](EnvTaskParams& t, int v) {
            if (v < 0 || v > 2) throw py::value_error("action_mode must be 0, 1 or 2");
            t.action_mode = static_cast<ActionMode>(v);
          })
      .def_readwrite("dt", &EnvTaskParams::dt)
      .def_readwrite("substeps", &EnvTaskParams::substeps)
      .def_readwrite("max_steps", &EnvTaskParams::max_steps)
      .def_readwrite("targets", &EnvTaskParams::targets)
      .def_readwrite("n_ahead", &EnvTaskParams::n_ahead)
      .def_readwrite("reach_radius", &EnvTaskParams::reach_radius)
      .def_readwrite("gate_size", &EnvTaskParams::gate_size)
      .def_readwrite("bound", &EnvTaskParams::bound)
      .def_readwrite("crash_z", &EnvTaskParams::crash_z)
      .def_readwrite("spawn_center", &EnvTaskParams::spawn_center)
      .def_readwrite("spawn_extent", &EnvTaskParams::spawn_extent)
      .def_readwrite("spawn_speed", &EnvTaskParams::spawn_speed)
      .def_readwrite("spawn_tilt", &EnvTaskParams::spawn_tilt)
      .def_readwrite("spawn_rate", &EnvTaskParams::spawn_rate)
      .def_readwrite("max_rate", &EnvTaskParams::max_rate)
      .def_readwrite("max_speed", &EnvTaskParams::max_speed)
      .def_readwrite("velocity_gain", &EnvTaskParams::velocity_gain)
      .def_readwrite("attitude_gain", &EnvTaskParams::attitude_gain)
      .def_readwrite("w_position", &EnvTaskParams::w_position)
      .def_readwrite("w_velocity", &EnvTaskParams::w_velocity)
      .def_readwrite("w_rate", &EnvTaskParams::w_rate)
      .def_readwrite("w_action", &EnvTaskParams::w_action)
      .def_readwrite("alive", &EnvTaskParams::alive)
      .def_readwrite("progress", &EnvTaskParams::progress)
      .def_readwrite("reached", &EnvTaskParams::reached)
      .def_readwrite("crash", &EnvTaskParams::crash)
      .def_readwrite("mass", &EnvTaskParams::mass)
      .def_readwrite("inertia", &EnvTaskParams::inertia)
      .def_readwrite("motor_constant", &EnvTaskParams::motor_constant)
      .def_readwrite("motor_lag", &EnvTaskParams::motor_lag)
      .def_readwrite("drag", &EnvTaskParams::drag)
      .def_readwrite("latency_steps", &EnvTaskParams::latency_steps)
      .def_readwrite("wind", &EnvTaskParams::wind)
      .def_readwrite("position_noise", &EnvTaskParams::position_noise)
      .def_readwrite("velocity_noise", &EnvTaskParams::velocity_noise)
      .def_readwrite("imu_noise", &EnvTaskParams::imu_noise)
      .def_readwrite("gyro_white", &EnvTaskParams::gyro_white)
      .def_readwrite("gyro_walk", &EnvTaskParams::gyro_walk)
      .def_readwrite("gyro_turn_on", &EnvTaskParams::gyro_turn_on)
      .def_readwrite("rate_d_cutoff_hz", &EnvTaskParams::rate_d_cutoff_hz)
      .def_readwrite("rate_i_scale", &EnvTaskParams::rate_i_scale)
      .def_readwrite("segment_s", &EnvTaskParams::segment_s)
      .def_readwrite("hold_s", &EnvTaskParams::hold_s)
      .def_readwrite("waypoint_jitter", &EnvTaskParams::waypoint_jitter)
      .def_readwrite("lookahead", &EnvTaskParams::lookahead)
      .def_readwrite("w_smooth", &EnvTaskParams::w_smooth)
      .def(
          "set_rate_gains",
          [](EnvTaskParams& t, const Eigen::Vector3d& k_p, const Eigen::Vector3d& k_i, const Eigen::Vector3d& k_d,
             double feed_forward, double integrator_limit) {
            t.rate_gains = RateControlGains{k_p, k_i, k_d, feed_forward, integrator_limit};
          },
          py::arg("k_p"), py::arg("k_i"), py::arg("k_d"), py::arg("feed_forward"), py::arg("integrator_limit"))
      .def_property_readonly("obs_size", &EnvTaskParams::obs_size);

  py::class_<EnvBatch>(m, "EnvBatch", "N envs of one task over a QuadrotorBatch (cpp/envs/env_batch.h).")
      .def(py::init([](const QuadrotorParams& params, const EnvTaskParams& task, std::int64_t n) {
             const std::string err = validate(params);
             if (!err.empty()) throw py::value_error(err);
             if (n < 1 || static_cast<std::size_t>(n) > QuadrotorBatch::kMaxSize) {
               throw py::value_error("num_envs must be an integer in [1, 2^32], got " + std::to_string(n));
             }
             try {
               return std::make_unique<EnvBatch>(params, task, static_cast<std::size_t>(n));
             } catch (const std::invalid_argument& e) {
               throw py::value_error(e.what());
             }
           }),
           py::arg("params"), py::arg("task"), py::arg("num_envs"))
      .def_property_readonly("size", &EnvBatch::size)
      .def_property_readonly("obs_size", &EnvBatch::obs_size)
      .def_property_readonly("batch", &EnvBatch::batch, py::return_value_policy::reference_internal,
                             "The QuadrotorBatch the envs fly (its state arrays are views).")
      .def(
          "reset",
          [](EnvBatch& e, std::optional<std::uint64_t> seed) {
            py::array_t<float> obs({static_cast<py::ssize_t>(e.size()), static_cast<py::ssize_t>(e.obs_size())});
            float* o = obs.mutable_data();
            {
              py::gil_scoped_release release;
              if (seed) {
                e.reset(*seed, o);
              } else {
                e.reset(o);
              }
            }
            return obs;
          },
          py::arg("seed") = py::none(), "Resets every env (seeding env i's stream with seed + i when given); obs.")
      .def(
          "step",
          [](EnvBatch& e, const py::handle& actions_obj, int nthreads) {
            const py::array arr = checked_array(actions_obj, "actions");
            const auto n = static_cast<py::ssize_t>(e.size());
            if (!(arr.ndim() == 2 && arr.shape(0) == n && arr.shape(1) == 4)) {
              throw py::value_error("actions must have shape " + expected_shape_str({n, 4}) + ", got " +
                                    shape_str(arr));
            }
            const carray<double> a = contiguous<double>(arr, "actions");
            py::array_t<float> obs({n, static_cast<py::ssize_t>(e.obs_size())});
            py::array_t<double> reward(n);
            py::array_t<bool> term(n), trunc(n);
            float* o = obs.mutable_data();
            double* r = reward.mutable_data();
            bool* te = term.mutable_data();
            bool* tr = trunc.mutable_data();
            const double* ap = a.data();
            try {
              py::gil_scoped_release release;
              e.step(ap, o, r, te, tr, nthreads);
            } catch (const std::invalid_argument& ex) {
              throw py::value_error(ex.what());
            }
            return py::make_tuple(obs, reward, term, trunc);
          },
          py::arg("actions"), py::arg("nthreads") = 0,
          "One step of every env: (obs, reward, terminated, truncated); next-step autoreset.")
      .def(
          "end_episodes",
          [](EnvBatch& e, const py::handle& mask_obj) {
            const py::array arr = checked_array(mask_obj, "mask");
            const auto n = static_cast<py::ssize_t>(e.size());
            if (!(arr.ndim() == 1 && arr.shape(0) == n && arr.dtype().kind() == 'b')) {
              throw py::value_error("mask must be a bool array of shape " + expected_shape_str({n}) + ", got " +
                                    shape_str(arr) + " " + std::string(py::str(arr.dtype())));
            }
            const carray<bool> m = contiguous<bool>(arr, "mask");
            e.end_episodes(m.data());
          },
          py::arg("mask"), "Ends the episodes of the envs where mask (N,) is True: the next step resets them.")
      .def_property_readonly("target_index",
                             [](const EnvBatch& e) { return py::array_t<int>(e.size(), e.target_index().data()); })
      .def_property_readonly("episode_steps",
                             [](const EnvBatch& e) { return py::array_t<int>(e.size(), e.episode_steps().data()); })
      .def_property_readonly("latency",
                             [](const EnvBatch& e) { return py::array_t<int>(e.size(), e.latency().data()); })
      .def(
          "reference",
          [](const EnvBatch& e, std::int64_t i, double t) {
            if (!e.task().reference()) throw py::value_error("the task has no timed reference (segment_s is [0, 0])");
            if (i < 0 || static_cast<std::size_t>(i) >= e.size()) throw py::index_error("env index out of range");
            py::array_t<double> out(9);
            e.reference_at(static_cast<std::size_t>(i), t, out.mutable_data());
            return out;
          },
          py::arg("env"), py::arg("t"),
          "Reference mode: env's reference p_W, v_W, a_W (9,) at time t [s] of its episode.")
      .def(
          "waypoints",
          [](const EnvBatch& e, std::int64_t i) {
            if (!e.task().reference()) throw py::value_error("the task has no timed reference (segment_s is [0, 0])");
            if (i < 0 || static_cast<std::size_t>(i) >= e.size()) throw py::index_error("env index out of range");
            const std::vector<double> w = e.waypoints(static_cast<std::size_t>(i));
            return py::array_t<double>({static_cast<py::ssize_t>(w.size() / 3), py::ssize_t(3)}, w.data());
          },
          py::arg("env"), "Reference mode: env's waypoints (K, 3) as jittered at its last reset.")
      .def_property_readonly("drawn_scales", [](const EnvBatch& e) {
        return py::array_t<double>({static_cast<py::ssize_t>(e.size()), py::ssize_t(5)}, e.drawn_scales().data());
      });
}

}  // namespace cufund::py_bind
