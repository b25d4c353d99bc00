// cufund._core.envs: the learning environments' batch (cpp/envs), stepped with the GIL released.
#include <array>
#include <stdexcept>

#include "env_batch.h"
#include "pybind_common.h"

namespace cufund::py_bind {

void define_envs(py::module_& m) {
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
