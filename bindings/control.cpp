// Bindings for cpp/control: control allocation and the SE(3) geometric controller's attitude law.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>

#include <cstring>

#include "allocation.h"
#include "attitude_control.h"
#include "geometric_control.h"
#include "position_control.h"
#include "pybind_common.h"
#include "rate_control.h"

namespace cufund::py_bind {
namespace {

// A finite (N,) vector, else ValueError naming the field. A float64 numpy (N,) array is read in place (the per-step
// common case, a few hundred nanoseconds cheaper than a conversion), anything else through the checked conversion.
template <int N>
Eigen::Matrix<double, N, 1> finite_vector(const py::handle& obj, const char* field) {
  Eigen::Matrix<double, N, 1> v;
  const auto arr = py::array_t<double>::check_(obj) ? py::reinterpret_borrow<py::array>(obj) : py::array();
  if (arr && arr.ndim() == 1 && arr.shape(0) == N) {
    const char* data = static_cast<const char*>(arr.data());
    const py::ssize_t stride = arr.strides(0);
    for (int i = 0; i < N; ++i) std::memcpy(&v[i], data + i * stride, sizeof(double));
  } else {
    auto a = as_float64(obj, field, {N});
    v = Eigen::Map<const Eigen::Matrix<double, N, 1>>(a.data());
  }
  if (!v.allFinite()) throw py::value_error(std::string(field) + " must be finite");
  return v;
}
const auto vec3 = finite_vector<3>;
const auto vec4 = finite_vector<4>;

double finite(const py::handle& x, const char* field) { return finite_arg(x, field); }

// A symmetric positive-definite, finite inertia matrix J (3, 3) [kg m^2].
Eigen::Matrix3d inertia_arg(const py::handle& J) {
  auto Ja = as_float64(J, "J", {3, 3});
  const Eigen::Matrix3d Jm = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(Ja.data());
  if (!Jm.allFinite()) throw py::value_error("J must be a finite 3x3 inertia matrix [kg m^2]");
  const double scale = Jm.cwiseAbs().maxCoeff();
  if (!((Jm - Jm.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale)) {
    throw py::value_error("J must be symmetric [kg m^2]");
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(Jm);
  if (!(eig.eigenvalues().minCoeff() > 1e-12 * scale && scale > 0)) {
    throw py::value_error("J must be positive definite [kg m^2]");
  }
  return Jm;
}

double mass_arg(const py::handle& m) {
  const double mass = finite_arg(m, "mass");
  if (!(mass > 0)) throw py::value_error("mass must be a finite number > 0 [kg], got " + std::to_string(mass));
  return mass;
}

// A fresh, read-only float64 (N,) array (no base, so a message can take it without a copy).
template <int N>
py::array_t<double> readonly_array(const Eigen::Matrix<double, N, 1>& v) {
  py::array_t<double> a(N);
  std::memcpy(a.mutable_data(), v.data(), N * sizeof(double));
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

double positive(const py::handle& x, const char* field) {
  const double v = finite_arg(x, field);
  if (!(v > 0)) throw py::value_error(std::string(field) + " must be > 0, got " + std::to_string(v));
  return v;
}

double non_negative(const py::handle& x, const char* field) {
  const double v = finite_arg(x, field);
  if (!(v >= 0)) throw py::value_error(std::string(field) + " must be >= 0, got " + std::to_string(v));
  return v;
}

const QuadrotorParams& params_arg(const py::handle& params) {
  if (!py::isinstance<QuadrotorParams>(params)) {
    throw py::type_error("params must be a cufund.QuadrotorParams (its .to_core()), got " + type_name(params));
  }
  const QuadrotorParams& p = params.cast<const QuadrotorParams&>();
  const std::string err = validate(p);
  if (!err.empty()) throw py::value_error(err);
  return p;
}

// A non-zero quaternion [w, x, y, z] normalised (left bit-identical when already unit).
Eigen::Vector4d normalised(const Eigen::Vector4d& q, const char* field) {
  const double norm = q.norm();
  if (!(norm >= 1e-6)) {
    throw py::value_error(std::string(field) + " must be a non-zero quaternion [w, x, y, z], got norm " +
                          std::to_string(norm));
  }
  return std::abs(norm - 1.0) <= 1e-12 ? q : Eigen::Vector4d(q / norm);
}

// A finite, non-zero quaternion [w, x, y, z], normalised (left bit-identical when already unit).
Eigen::Vector4d unit_quaternion(const py::handle& obj, const char* field) {
  return normalised(vec4(obj, field), field);
}

// (q_WB_d (4,), thrust [N], rotor_speeds (4,), achieved thrust [N], achieved torque_B (3,)), arrays read-only.
py::tuple geometric_step_tuple(const GeometricStep& s) {
  return py::make_tuple(readonly_array<4>(s.command.q_WB_d), s.command.thrust,
                        readonly_array<4>(s.allocation.rotor_speeds), s.allocation.achieved[0],
                        readonly_array<3>(Eigen::Vector3d(s.allocation.achieved.tail<3>())));
}

py::tuple command_tuple(const GeometricAttitudeCommand& c) {
  return py::make_tuple(c.thrust, Eigen::Vector3d(c.torque_B), Eigen::Vector4d(c.q_WB_d));
}

}  // namespace

void define_control(py::module_& m) {
  py::class_<ControlAllocator>(m, "ControlAllocator",
                               "Prioritising allocation: roll/pitch first, then collective thrust, then yaw.")
      .def(py::init([](const py::handle& params) { return ControlAllocator(params_arg(params)); }), py::arg("params"))
      .def(
          "allocate",
          [](const ControlAllocator& a, const py::handle& thrust, const py::handle& torque_B) {
            const AllocationResult r = a.allocate(finite(thrust, "thrust"), vec3(torque_B, "torque_B"));
            return py::make_tuple(Eigen::Vector4d(r.rotor_speeds), Eigen::Vector4d(r.achieved),
                                  py::make_tuple(r.saturation[0], r.saturation[1], r.saturation[2], r.saturation[3]));
          },
          py::arg("thrust"), py::arg("torque_B"),
          "(rotor_speeds (4,) [rad/s], achieved [f, Mx, My, Mz] (4,), saturation signs (4 ints)).")
      .def_property_readonly("max_thrust", &ControlAllocator::max_thrust, "All rotors at full speed [N].");

  py::class_<PositionControl>(
      m, "PositionControl",
      "The arithmetic of one PX4-style position-control step (cufund.control.PositionController keeps the "
      "flight-mode logic): position P -> velocity PID -> limited thrust vector -> attitude setpoint.")
      .def(py::init([](const py::handle& mass, const py::handle& gravity, const py::handle& max_thrust,
                       const py::handle& vel_d_cutoff_hz, const py::handle& transfer_tau) {
             return PositionControl(mass_arg(mass), positive(gravity, "gravity"), positive(max_thrust, "max_thrust"),
                                    non_negative(vel_d_cutoff_hz, "vel_d_cutoff_hz"),
                                    positive(transfer_tau, "transfer_tau"));
           }),
           py::arg("mass"), py::arg("gravity"), py::arg("max_thrust"), py::arg("vel_d_cutoff_hz"),
           py::arg("transfer_tau"),
           "mass [kg], gravity [m/s^2], max_thrust [N], the velocity derivative's low-pass cutoff [Hz] (0: none), "
           "the mode-switch hand-over's decay time [s].")
      .def(
          "set_gains",
          [](PositionControl& c, const py::handle& k_p, const py::handle& k_v, const py::handle& k_i,
             const py::handle& k_d, const py::handle& xy_vel_max, const py::handle& z_vel_max_up,
             const py::handle& z_vel_max_dn, const py::handle& tilt_max, const py::handle& thr_min,
             const py::handle& thr_max) {
            c.set_gains({vec3(k_p, "k_p"), vec3(k_v, "k_v"), vec3(k_i, "k_i"), vec3(k_d, "k_d"),
                         finite(xy_vel_max, "xy_vel_max"), finite(z_vel_max_up, "z_vel_max_up"),
                         finite(z_vel_max_dn, "z_vel_max_dn"), finite(tilt_max, "tilt_max"), finite(thr_min, "thr_min"),
                         finite(thr_max, "thr_max")});
          },
          py::arg("k_p"), py::arg("k_v"), py::arg("k_i"), py::arg("k_d"), py::arg("xy_vel_max"),
          py::arg("z_vel_max_up"), py::arg("z_vel_max_dn"), py::arg("tilt_max"), py::arg("thr_min"), py::arg("thr_max"),
          "Gains (x, y, z) and limits as in cufund.control.PositionControlParams.")
      .def("reset", &PositionControl::reset, "Integrator, derivative filter and hand-over to their initial state.")
      .def(
          "filter_velocity",
          [](PositionControl& c, const py::handle& v_W, const py::handle& dt) {
            c.filter_velocity(vec3(v_W, "v_W"), positive(dt, "dt"));
          },
          py::arg("v_W"), py::arg("dt"), "Steps the measured velocity's derivative filter only (attitude mode).")
      .def(
          "step",
          [](PositionControl& c, const py::handle& t, const py::handle& dt, const py::handle& p_W,
             const py::handle& v_W, const py::handle& p_sp, const py::handle& v_sp, const py::handle& a_sp,
             const py::handle& yaw, const py::handle& position_mode, const py::handle& handover) {
            Eigen::Vector3d h;
            if (!handover.is_none()) h = vec3(handover, "handover");
            const PositionControlOutput out =
                c.step(finite(t, "t"), positive(dt, "dt"), vec3(p_W, "p_W"), vec3(v_W, "v_W"), vec3(p_sp, "p_sp"),
                       vec3(v_sp, "v_sp"), vec3(a_sp, "a_sp"), finite(yaw, "yaw"),
                       bool_arg(position_mode, "position_mode"), handover.is_none() ? nullptr : &h);
            return py::make_tuple(readonly_array<4>(out.q_WB), out.thrust);
          },
          py::arg("t"), py::arg("dt"), py::arg("p_W"), py::arg("v_W"), py::arg("p_sp"), py::arg("v_sp"),
          py::arg("a_sp"), py::arg("yaw"), py::arg("position_mode"), py::arg("handover") = py::none(),
          "One step at t [s], dt [s] after the last: (q_WB setpoint (4,) read-only, thrust [N]). position_mode "
          "False tracks v_sp only; handover (3,) [m/s^2], at a mode switch, is the acceleration last commanded.")
      .def_property(
          "vel_int", [](const PositionControl& c) { return Eigen::Vector3d(c.vel_int); },
          [](PositionControl& c, const py::handle& v) { c.vel_int = vec3(v, "vel_int"); },
          "Velocity integrator (3,) [m/s^2].")
      .def_property_readonly(
          "acc_filt", [](const PositionControl& c) { return Eigen::Vector3d(c.acc_filt()); },
          "Low-passed measured acceleration (3,) [m/s^2] that D acts on.");

  py::class_<AttitudeControl>(m, "AttitudeControl",
                              "PX4-style attitude P with reduced yaw priority: attitude error -> body-rate setpoint.")
      .def(py::init<>())
      .def(
          "set_gains",
          [](AttitudeControl& c, const py::handle& k, const py::handle& rate_max, const py::handle& yaw_weight) {
            const double w = finite(yaw_weight, "yaw_weight");
            if (!(w >= 0.0 && w <= 1.0)) throw py::value_error("yaw_weight must be in [0, 1]");
            c.k = vec3(k, "k");
            c.rate_max = vec3(rate_max, "rate_max");
            c.yaw_weight = w;
          },
          py::arg("k"), py::arg("rate_max"), py::arg("yaw_weight"),
          "Gains (roll, pitch, their mean) [1/s], rate limits (3,) [rad/s], yaw weight in [0, 1].")
      .def(
          "rate_setpoint",
          [](const AttitudeControl& c, const py::handle& q_WB, const py::handle& q_WB_d, const py::handle& yaw_rate) {
            return readonly_array<3>(attitude_rate_setpoint(vec4(q_WB, "q_WB"), vec4(q_WB_d, "q_WB_d"),
                                                            finite(yaw_rate, "yaw_rate"), c.k, c.rate_max,
                                                            c.yaw_weight));
          },
          py::arg("q_WB"), py::arg("q_WB_d"), py::arg("yaw_rate"),
          "Body-rate setpoint (3,) [rad/s], read-only, for attitude q_WB towards q_WB_d with the yaw-rate "
          "feed-forward [rad/s] about world z.");

  py::class_<RateControl>(m, "RateControl",
                          "One PX4-style body-rate PID step with prioritising allocation to rotor speeds.")
      .def(py::init([](const py::handle& params, const py::handle& d_cutoff_hz, const py::handle& i_scale) {
             return RateControl(params_arg(params), non_negative(d_cutoff_hz, "d_cutoff_hz"),
                                positive(i_scale, "i_scale"));
           }),
           py::arg("params"), py::arg("d_cutoff_hz"), py::arg("i_scale"),
           "params: a cufund.QuadrotorParams (its .to_core()); the rate derivative's low-pass cutoff [Hz] "
           "(0: none); i_scale [rad/s]: the rate error at which the integrator stops growing.")
      .def(
          "set_gains",
          [](RateControl& c, const py::handle& k_p, const py::handle& k_i, const py::handle& k_d,
             const py::handle& feed_forward, const py::handle& integrator_limit) {
            c.set_gains({vec3(k_p, "k_p"), vec3(k_i, "k_i"), vec3(k_d, "k_d"), finite(feed_forward, "feed_forward"),
                         finite(integrator_limit, "integrator_limit")});
          },
          py::arg("k_p"), py::arg("k_i"), py::arg("k_d"), py::arg("feed_forward"), py::arg("integrator_limit"),
          "Gains (roll, pitch, yaw) as in cufund.control.RateControlParams.")
      .def("reset", &RateControl::reset, "Integrator and derivative filter to their initial state.")
      .def(
          "step",
          [](RateControl& c, const py::handle& w_B, const py::handle& w_sp, const py::handle& thrust,
             const py::handle& dt) {
            const AllocationResult r =
                c.step(vec3(w_B, "w_B"), vec3(w_sp, "w_sp"), finite(thrust, "thrust"), positive(dt, "dt"));
            return py::make_tuple(readonly_array<4>(r.rotor_speeds), r.achieved[0],
                                  readonly_array<3>(Eigen::Vector3d(r.achieved.tail<3>())),
                                  py::make_tuple(r.saturation[0], r.saturation[1], r.saturation[2], r.saturation[3]));
          },
          py::arg("w_B"), py::arg("w_sp"), py::arg("thrust"), py::arg("dt"),
          "One step with measured rate w_B (3,) [rad/s], setpoint w_sp (3,) [rad/s], collective thrust [N], dt [s] "
          "after the last: (rotor_speeds (4,) [rad/s], achieved thrust [N], achieved torque_B (3,) [N m], "
          "saturation signs of [f, Mx, My, Mz]); arrays read-only.")
      .def_property(
          "rate_int", [](const RateControl& c) { return Eigen::Vector3d(c.rate_int); },
          [](RateControl& c, const py::handle& v) { c.rate_int = vec3(v, "rate_int"); },
          "Rate integrator (3,) [rad/s^2].");

  py::class_<GeometricControl>(m, "GeometricControl",
                               "The SE(3) controller's force law, attitude law and allocation, one call per step "
                               "(cufund.control.GeometricController keeps the flight-mode logic).")
      .def(py::init([](const py::handle& params, const py::handle& transfer_tau) {
             return GeometricControl(params_arg(params), positive(transfer_tau, "transfer_tau"));
           }),
           py::arg("params"), py::arg("transfer_tau"),
           "params: a cufund.QuadrotorParams (its .to_core()); the mode-switch hand-over's decay time [s].")
      .def(
          "set_gains",
          [](GeometricControl& c, const py::handle& k_x, const py::handle& k_v, const py::handle& k_R,
             const py::handle& k_W) {
            c.set_gains(finite(k_x, "k_x"), finite(k_v, "k_v"), vec3(k_R, "k_R"), vec3(k_W, "k_W"));
          },
          py::arg("k_x"), py::arg("k_v"), py::arg("k_R"), py::arg("k_W"),
          "k_x [m/s^2 per m], k_v [m/s^2 per m/s], k_R (3,) [rad/s^2 per rad], k_W (3,) [rad/s^2 per rad/s].")
      .def("reset", &GeometricControl::reset, "Clears the mode-switch hand-over.")
      .def(
          "step_force",
          [](GeometricControl& c, const py::handle& t, const py::handle& p_W, const py::handle& v_W,
             const py::handle& q_WB, const py::handle& w_B, const py::handle& p_sp, const py::handle& v_sp,
             const py::handle& a_sp, const py::handle& j_sp, const py::handle& yaw, const py::handle& yaw_rate,
             const py::handle& position_mode, const py::handle& handover) {
            Eigen::Vector3d h;
            if (!handover.is_none()) h = vec3(handover, "handover");
            return geometric_step_tuple(
                c.step_force(finite(t, "t"), vec3(p_W, "p_W"), vec3(v_W, "v_W"), unit_quaternion(q_WB, "q_WB"),
                             vec3(w_B, "w_B"), vec3(p_sp, "p_sp"), vec3(v_sp, "v_sp"), vec3(a_sp, "a_sp"),
                             vec3(j_sp, "j_sp"), finite(yaw, "yaw"), finite(yaw_rate, "yaw_rate"),
                             bool_arg(position_mode, "position_mode"), handover.is_none() ? nullptr : &h));
          },
          py::arg("t"), py::arg("p_W"), py::arg("v_W"), py::arg("q_WB"), py::arg("w_B"), py::arg("p_sp"),
          py::arg("v_sp"), py::arg("a_sp"), py::arg("j_sp"), py::arg("yaw"), py::arg("yaw_rate"),
          py::arg("position_mode"), py::arg("handover") = py::none(),
          "Position (or, position_mode False, velocity) mode at t [s]; handover (3,) [N], at a mode switch, is the "
          "force last commanded. (q_WB_d (4,), thrust [N], rotor_speeds (4,) [rad/s], achieved thrust [N], "
          "achieved torque_B (3,) [N m]), arrays read-only.")
      .def(
          "step_attitude",
          [](const GeometricControl& c, const py::handle& q_WB, const py::handle& w_B, const py::handle& q_WB_d,
             const py::handle& thrust, const py::handle& yaw_rate) {
            return geometric_step_tuple(c.step_attitude(unit_quaternion(q_WB, "q_WB"), vec3(w_B, "w_B"),
                                                        unit_quaternion(q_WB_d, "q_WB_d"), finite(thrust, "thrust"),
                                                        finite(yaw_rate, "yaw_rate")));
          },
          py::arg("q_WB"), py::arg("w_B"), py::arg("q_WB_d"), py::arg("thrust"), py::arg("yaw_rate"),
          "Attitude mode: as step_force's result for a desired attitude q_WB_d, thrust [N] and yaw rate [rad/s].");

  m.def(
      "attitude_from_thrust_and_yaw",
      [](const py::handle& z_B, const py::handle& yaw) {
        const Eigen::Vector3d z = vec3(z_B, "z_B");
        if (std::abs(z.norm() - 1.0) > 1e-6) throw py::value_error("z_B must be a unit vector");
        return Eigen::Matrix3d(attitude_from_thrust_and_yaw(z, finite(yaw, "yaw")));
      },
      py::arg("z_B"), py::arg("yaw"),
      "R_WB (3, 3) with body z along unit z_B and body x along the heading yaw, projected (PX4's bodyzToAttitude).");
  m.def(
      "geometric_from_force",
      [](const py::handle& J, const py::handle& mass, const py::handle& k_R, const py::handle& k_W,
         const py::handle& q_WB, const py::handle& w_B, const py::handle& F_W, const py::handle& j_W,
         const py::handle& yaw, const py::handle& yaw_rate) {
        const Eigen::Matrix3d Jm = inertia_arg(J);
        return command_tuple(geometric_from_force(Jm, mass_arg(mass), vec3(k_R, "k_R"), vec3(k_W, "k_W"),
                                                  unit_quaternion(q_WB, "q_WB"), vec3(w_B, "w_B"), vec3(F_W, "F_W"),
                                                  vec3(j_W, "j_W"), finite(yaw, "yaw"), finite(yaw_rate, "yaw_rate")));
      },
      py::arg("J"), py::arg("mass"), py::arg("k_R"), py::arg("k_W"), py::arg("q_WB"), py::arg("w_B"), py::arg("F_W"),
      py::arg("j_W"), py::arg("yaw"), py::arg("yaw_rate"),
      "Lee et al.'s attitude law from a desired world force: (thrust [N], torque_B (3,) [N m], q_WB_d (4,)).");
  m.def(
      "geometric_from_attitude",
      [](const py::handle& J, const py::handle& k_R, const py::handle& k_W, const py::handle& q_WB,
         const py::handle& w_B, const py::handle& q_WB_d, const py::handle& thrust, const py::handle& yaw_rate) {
        const Eigen::Matrix3d Jm = inertia_arg(J);
        return command_tuple(geometric_from_attitude(
            Jm, vec3(k_R, "k_R"), vec3(k_W, "k_W"), unit_quaternion(q_WB, "q_WB"), vec3(w_B, "w_B"),
            unit_quaternion(q_WB_d, "q_WB_d"), finite(thrust, "thrust"), finite(yaw_rate, "yaw_rate")));
      },
      py::arg("J"), py::arg("k_R"), py::arg("k_W"), py::arg("q_WB"), py::arg("w_B"), py::arg("q_WB_d"),
      py::arg("thrust"), py::arg("yaw_rate"),
      "Lee et al.'s attitude law for a desired attitude and thrust: (thrust, torque_B (3,), q_WB_d (4,)).");
}

}  // namespace cufund::py_bind
