// Bindings of cpp/dynamics: parameters, control allocation and the batched rigid-body integrator.
#include <cmath>
#include <memory>

#include "mixer.h"
#include "pybind_common.h"
#include "quadrotor_batch.h"

namespace cufund::py_bind {
namespace {

void check_params(const QuadrotorParams& params) {
  const std::string err = validate(params);
  if (!err.empty()) throw py::value_error(err);
}

py::array_t<double, py::array::c_style> command_array(const py::handle& obj, std::size_t n) {
  const auto nn = static_cast<py::ssize_t>(n);
  py::array arr = py::array::ensure(obj);
  if (n == 1 && arr && arr.ndim() == 1) return as_float64(obj, "rotor_speed_cmd", {kNumRotors});
  return as_float64(obj, "rotor_speed_cmd", {nn, kNumRotors});
}

void raise_step_error(const StepResult& r, double dt, const py::array& cmd) {
  switch (r.status) {
    case StepStatus::kOk:
      return;
    case StepStatus::kBadTimeStep: {
      std::ostringstream os;
      os << "dt must be a finite number > 0 [s] of at most 1e9 integration sub-steps, got " << dt;
      throw py::value_error(os.str());
    }
    case StepStatus::kNonFiniteCommand: {
      const double bad = static_cast<const double*>(cmd.data())[r.index];
      std::ostringstream msg;
      msg << "rotor_speed_cmd must be finite [rad/s], got " << bad << " for vehicle " << r.index / kNumRotors
          << ", rotor " << r.index % kNumRotors + 1;
      throw py::value_error(msg.str());
    }
  }
}

}  // namespace

void define_dynamics(py::module_& m) {
  py::enum_<RotorLayout>(m, "RotorLayout", "Rotor arrangement and numbering (PX4 airframe reference).")
      .value("PLUS", RotorLayout::kPlus, "1 front, 2 right, 3 back, 4 left; 1 and 3 clockwise")
      .value("X", RotorLayout::kX, "PX4 quad-x: 1 front-right, 2 rear-left, 3 front-left, 4 rear-right; 1, 2 CCW");

  py::class_<QuadrotorParams>(m, "QuadrotorParams",
                              "Plain C++ parameter record; use cufund.QuadrotorParams, which validates and documents.")
      .def(py::init<>())
      .def_readwrite("mass", &QuadrotorParams::mass)
      .def_readwrite("inertia", &QuadrotorParams::inertia)
      .def_readwrite("arm_length", &QuadrotorParams::arm_length)
      .def_readwrite("layout", &QuadrotorParams::layout)
      .def_readwrite("k_f", &QuadrotorParams::k_f)
      .def_readwrite("c_m", &QuadrotorParams::c_m)
      .def_readwrite("tau_m", &QuadrotorParams::tau_m)
      .def_readwrite("rotor_speed_min", &QuadrotorParams::rotor_speed_min)
      .def_readwrite("rotor_speed_max", &QuadrotorParams::rotor_speed_max)
      .def_readwrite("rotor_drag_xy", &QuadrotorParams::rotor_drag_xy)
      .def_readwrite("rotor_drag_z", &QuadrotorParams::rotor_drag_z)
      .def_readwrite("body_drag", &QuadrotorParams::body_drag)
      .def_readwrite("gravity", &QuadrotorParams::gravity)
      .def_readwrite("ground_plane", &QuadrotorParams::ground_plane)
      .def_readwrite("max_integration_step", &QuadrotorParams::max_integration_step);

  m.def("validate_params", &validate, py::arg("params"),
        "Empty string when the parameters are physical, else a message naming the field.");
  m.def(
      "allocation_matrix",
      [](const QuadrotorParams& p) {
        check_params(p);
        return Eigen::Matrix4d(allocation_matrix(p));
      },
      py::arg("params"), "A (4, 4): rotor thrusts [N] -> [f, M_x, M_y, M_z] in body FLU (paper eq. 1).");
  m.def(
      "allocation_matrix_inverse",
      [](const QuadrotorParams& p) {
        check_params(p);
        return Eigen::Matrix4d(allocation_matrix_inverse(p));
      },
      py::arg("params"), "A^-1 (4, 4): [f, M_x, M_y, M_z] -> rotor thrusts [N], unsaturated.");
  m.def(
      "rotor_positions",
      [](const QuadrotorParams& p) {
        check_params(p);
        const RotorGeometry g = rotor_geometry(p);
        Eigen::Matrix<double, 4, 3, Eigen::RowMajor> out;
        for (int i = 0; i < kNumRotors; ++i) out.row(i) = g.position_B[i].transpose();
        return out;
      },
      py::arg("params"), "Rotor centres in body FLU [m], shape (4, 3), PX4 numbering.");
  m.def(
      "rotor_spins",
      [](const QuadrotorParams& p) {
        check_params(p);
        const RotorGeometry g = rotor_geometry(p);
        return Eigen::Vector4d(g.spin[0], g.spin[1], g.spin[2], g.spin[3]);
      },
      py::arg("params"), "+1 for a rotor spinning counter-clockwise seen from above, -1 clockwise.");

  py::class_<QuadrotorBatch>(m, "QuadrotorBatch",
                             "N quadrotors integrated together; state arrays are views into C++ memory.")
      .def(py::init([](const QuadrotorParams& p, std::int64_t n) {
             check_params(p);
             if (n < 1) throw py::value_error("n must be an integer >= 1, got " + std::to_string(n));
             return std::make_unique<QuadrotorBatch>(p, static_cast<std::size_t>(n));
           }),
           py::arg("params"), py::arg("n"))
      .def_property_readonly("size", &QuadrotorBatch::size)
      .def_property_readonly("params", &QuadrotorBatch::params)
      .def_property("time", &QuadrotorBatch::time, &QuadrotorBatch::set_time, "Simulated time [s].")
      .def_property_readonly("hover_rotor_speed", &QuadrotorBatch::hover_rotor_speed)
      .def("reset", &QuadrotorBatch::reset, "All vehicles at the origin, level, at rest; time 0.")
#define CUFUND_VIEW(name, field, rows, doc)                                                       \
  .def_property_readonly(                                                                          \
      name,                                                                                        \
      [](py::object self) {                                                                        \
        auto& b = self.cast<QuadrotorBatch&>();                                                    \
        return soa_view(b.row(QuadrotorBatch::field), b.size(), rows, self);                      \
      },                                                                                           \
      doc)
      CUFUND_VIEW("p", kP, 3, "Position p_W [m], (N, 3) view.")
      CUFUND_VIEW("v", kV, 3, "Velocity v_W [m/s], (N, 3) view.")
      CUFUND_VIEW("q", kQ, 4, "Attitude q_WB [w, x, y, z], (N, 4) view.")
      CUFUND_VIEW("w", kW, 3, "Body rate w_B [rad/s], (N, 3) view.")
      CUFUND_VIEW("rotor_speeds", kRotor, 4, "Rotor speeds [rad/s], (N, 4) view, PX4 numbering.")
      CUFUND_VIEW("wind_W", kWind, 3, "Wind velocity in world frame [m/s], (N, 3) view, held over a step.")
      CUFUND_VIEW("force_ext_W", kForceExt, 3, "External force, world frame [N], (N, 3) view, held over a step.")
      CUFUND_VIEW("torque_ext_B", kTorqueExt, 3, "External torque, body frame [N m], (N, 3) view, held over a step.")
      CUFUND_VIEW("accel_W", kAccel, 3, "Acceleration dv_W/dt at the end of the last step [m/s^2], (N, 3) view.")
      CUFUND_VIEW("alpha_B", kAlpha, 3, "Angular acceleration dw_B/dt at the end of the last step [rad/s^2], (N, 3).")
#undef CUFUND_VIEW
      .def(
          "step",
          [](QuadrotorBatch& b, double dt, const py::handle& cmd_obj, int nthreads) {
            py::array_t<double, py::array::c_style> cmd = command_array(cmd_obj, b.size());
            StepResult r;
            if (b.size() >= 64) {
              py::gil_scoped_release release;
              r = b.step(dt, cmd.data(), nthreads);
            } else {
              r = b.step(dt, cmd.data(), nthreads);
            }
            raise_step_error(r, dt, cmd);
          },
          py::arg("dt"), py::arg("rotor_speed_cmd"), py::arg("nthreads") = 0,
          "Advance by dt [s] holding rotor_speed_cmd (N, 4) [rad/s]; nthreads 0 = all cores.");
}

}  // namespace cufund::py_bind
