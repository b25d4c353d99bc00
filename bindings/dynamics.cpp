// Bindings of cpp/dynamics: parameters, control allocation and the batched rigid-body integrator.
#include <cmath>
#include <limits>
#include <memory>

#include "atmosphere.h"
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

const char* row_name(int row) {
  if (row < QuadrotorBatch::kV) return "p";
  if (row < QuadrotorBatch::kQ) return "v";
  if (row < QuadrotorBatch::kW) return "q";
  if (row < QuadrotorBatch::kRotor) return "w";
  if (row < QuadrotorBatch::kWind) return "rotor_speeds";
  if (row < QuadrotorBatch::kForceExt) return "wind_W";
  if (row < QuadrotorBatch::kTorqueExt) return "force_ext_W";
  if (row < QuadrotorBatch::kEta) return "torque_ext_B";
  if (row < QuadrotorBatch::kOmegaMax) return "rotor_efficiency";
  if (row < QuadrotorBatch::kAccel) return "max_rotor_speed";
  if (row < QuadrotorBatch::kAlpha) return "accel_W";
  if (row < QuadrotorBatch::kFloorZ) return "alpha_B";
  return "floor_z/ceiling_z";
}

void raise_step_error(const StepResult& r, double dt, const py::array& cmd, std::size_t n) {
  std::ostringstream os;
  switch (r.status) {
    case StepStatus::kOk: return;
    case StepStatus::kBadTimeStep:
      os << "dt must be a finite number > 0 [s], got " << dt;
      throw py::value_error(os.str());
    case StepStatus::kTooManySubsteps:
      os << "dt must need at most " << QuadrotorBatch::max_substeps()
         << " integration sub-steps (dt / max_integration_step; raise cufund.limits.configure(step_max_substeps=...)),"
            " got dt = "
         << dt << " s";
      throw py::value_error(os.str());
    case StepStatus::kNonFiniteCommand: {
      const double bad = static_cast<const double*>(cmd.data())[r.index];
      os << "rotor_speed_cmd must be finite [rad/s], got " << bad << " for vehicle " << r.index / kNumRotors
         << ", rotor " << r.index % kNumRotors + 1;
      throw py::value_error(os.str());
    }
    case StepStatus::kNonFiniteState: {
      const auto row = static_cast<int>(r.index / static_cast<std::int64_t>(n));
      os << "state " << row_name(row) << " of vehicle " << r.index % static_cast<std::int64_t>(n)
         << " must be finite before a step, got a NaN or inf (written through the state view?)";
      throw py::value_error(os.str());
    }
    case StepStatus::kDiverged: {
      const auto row = static_cast<int>(r.index / static_cast<std::int64_t>(n));
      os << "the step diverged: state " << row_name(row) << " of vehicle " << r.index % static_cast<std::int64_t>(n)
         << " is NaN or inf after it; the state, command and held inputs (wind_W, force_ext_W, torque_ext_B) are "
            "beyond what the model integrates (state left as it is; reset or rewrite it)";
      throw py::value_error(os.str());
    }
    case StepStatus::kZeroQuaternion:
      os << "state q of vehicle " << r.index << " must be a non-zero quaternion [w, x, y, z], got norm < 1e-6";
      throw py::value_error(os.str());
  }
}

const QuadrotorParams& params_arg(const py::handle& obj) {
  if (!py::isinstance<QuadrotorParams>(obj)) {
    throw py::type_error("params must be a cufund.QuadrotorParams (its .to_core()), got " + type_name(obj));
  }
  const QuadrotorParams& p = obj.cast<const QuadrotorParams&>();
  check_params(p);
  return p;
}

// A read-only (n, rows) view: rows whose values are checked by a setter.
py::array readonly_view(QuadrotorBatch& b, int field, int rows, py::handle owner) {
  py::array a = soa_view(b.row(field), b.size(), rows, owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

// Copies an (n, rows) C-contiguous array into SoA rows starting at `field`.
void write_rows(QuadrotorBatch& b, int field, int rows, const double* src) {
  const std::size_t n = b.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < rows; ++k) b.row(field + k)[i] = src[i * static_cast<std::size_t>(rows) + k];
  }
}

}  // namespace

void define_dynamics(py::module_& m) {
  py::class_<GroundEffectParams>(m, "GroundEffectParams",
                                 "Ground and ceiling effect constants (cpp/dynamics/ground_effect.h); use "
                                 "cufund.vehicle.ground_effect.GroundEffectConfig.")
      .def(py::init<>())
      .def_readwrite("enabled", &GroundEffectParams::enabled)
      .def_readwrite("rotor_radius", &GroundEffectParams::rotor_radius)
      .def_readwrite("rotor_spacing", &GroundEffectParams::rotor_spacing)
      .def_readwrite("body_distance", &GroundEffectParams::body_distance)
      .def_readwrite("k_body", &GroundEffectParams::k_body)
      .def_readwrite("ceiling_k1", &GroundEffectParams::ceiling_k1)
      .def_readwrite("ceiling_k2", &GroundEffectParams::ceiling_k2)
      .def_readwrite("min_height", &GroundEffectParams::min_height)
      .def_readwrite("rotor_plane_height", &GroundEffectParams::rotor_plane_height);
  py::enum_<WindShear>(m, "WindShear", "Mean wind profile with height.")
      .value("NONE", WindShear::kNone)
      .value("LOG", WindShear::kLog)
      .value("POWER", WindShear::kPower);
  py::class_<GustEvent>(m, "GustEvent", "A 1-cosine gust; use cufund.worlds.gusts.GustConfig.")
      .def(py::init<>())
      .def_readwrite("t_start", &GustEvent::t_start)
      .def_readwrite("duration", &GustEvent::duration)
      .def_readwrite("amplitude", &GustEvent::amplitude)
      .def_readwrite("direction", &GustEvent::direction)
      .def(
          py::pickle([](const GustEvent& g) { return py::make_tuple(g.t_start, g.duration, g.amplitude, g.direction); },
                     [](const py::tuple& t) {
                       GustEvent g;
                       g.t_start = t[0].cast<double>();
                       g.duration = t[1].cast<double>();
                       g.amplitude = t[2].cast<double>();
                       g.direction = t[3].cast<double>();
                       return g;
                     }));
  py::class_<AtmosphereParams>(m, "AtmosphereParams",
                               "The atmosphere's constants (cpp/dynamics/atmosphere.h); use "
                               "cufund.worlds.atmosphere.AtmosphereConfig.")
      .def(py::init<>())
      .def_readwrite("wind_20ft", &AtmosphereParams::wind_20ft)
      .def_readwrite("direction", &AtmosphereParams::direction)
      .def_readwrite("turbulence", &AtmosphereParams::turbulence)
      .def_readwrite("shear", &AtmosphereParams::shear)
      .def_readwrite("roughness_z0", &AtmosphereParams::roughness_z0)
      .def_readwrite("shear_exponent", &AtmosphereParams::shear_exponent)
      .def_readwrite("min_airspeed", &AtmosphereParams::min_airspeed)
      .def_readwrite("update_period", &AtmosphereParams::update_period)
      .def_readwrite("seed", &AtmosphereParams::seed)
      .def_readwrite("gusts", &AtmosphereParams::gusts)
      .def(
          "set_grid",
          [](AtmosphereParams& a, const py::handle& x, const py::handle& y, const py::handle& z,
             const py::handle& wind) {
            auto ax = [](const py::handle& o, const char* name) {
              py::array arr = checked_array(o, name);
              if (arr.ndim() != 1)
                throw py::value_error(std::string(name) + " must be a 1-D axis, got " + shape_str(arr));
              auto c = as_float64(o, name, {arr.shape(0)});
              return std::vector<double>(c.data(), c.data() + c.size());
            };
            std::vector<double> gx = ax(x, "x"), gy = ax(y, "y"), gz = ax(z, "z");
            const auto nx = static_cast<py::ssize_t>(gx.size()), ny = static_cast<py::ssize_t>(gy.size()),
                       nz = static_cast<py::ssize_t>(gz.size());
            auto w = as_float64(wind, "wind", {nx, ny, nz, 3});
            a.grid_x = std::move(gx);
            a.grid_y = std::move(gy);
            a.grid_z = std::move(gz);
            a.grid_wind.assign(w.data(), w.data() + w.size());
          },
          py::arg("x"), py::arg("y"), py::arg("z"), py::arg("wind"),
          "Sets the wind grid: axes x (nx,), y (ny,), z (nz,) [m], wind (nx, ny, nz, 3) [m/s].")
      .def_property_readonly("has_grid", [](const AtmosphereParams& a) { return !a.grid_wind.empty(); })
      .def(py::pickle(
          [](const AtmosphereParams& a) {
            return py::make_tuple(a.wind_20ft, a.direction, a.turbulence, static_cast<int>(a.shear), a.roughness_z0,
                                  a.shear_exponent, a.min_airspeed, a.update_period, a.seed, a.gusts, a.grid_x,
                                  a.grid_y, a.grid_z, a.grid_wind);
          },
          [](const py::tuple& t) {
            AtmosphereParams a;
            a.wind_20ft = t[0].cast<double>();
            a.direction = t[1].cast<double>();
            a.turbulence = t[2].cast<bool>();
            a.shear = static_cast<WindShear>(t[3].cast<int>());
            a.roughness_z0 = t[4].cast<double>();
            a.shear_exponent = t[5].cast<double>();
            a.min_airspeed = t[6].cast<double>();
            a.update_period = t[7].cast<double>();
            a.seed = t[8].cast<std::uint64_t>();
            a.gusts = t[9].cast<std::vector<GustEvent>>();
            a.grid_x = t[10].cast<std::vector<double>>();
            a.grid_y = t[11].cast<std::vector<double>>();
            a.grid_z = t[12].cast<std::vector<double>>();
            a.grid_wind = t[13].cast<std::vector<double>>();
            return a;
          }));
  m.def(
      "validate_atmosphere", [](const AtmosphereParams& a) { return validate(a); }, py::arg("params"),
      "Empty string when the atmosphere's constants are usable, else a message naming the field.");
  m.def(
      "dryden_scales",
      [](const py::handle& h, const py::handle& w20) {
        const DrydenScales d = dryden_scales(finite_arg(h, "h"), finite_arg(w20, "wind_20ft"));
        py::dict out;
        out["sigma_u"] = d.sigma_u;
        out["sigma_v"] = d.sigma_v;
        out["sigma_w"] = d.sigma_w;
        out["L_u"] = d.L_u;
        out["L_v"] = d.L_v;
        out["L_w"] = d.L_w;
        return out;
      },
      py::arg("h"), py::arg("wind_20ft"),
      "Dryden (MIL-F-8785C low altitude) intensities sigma_u/v/w [m/s] and scale lengths L_u/v/w [m] at height h [m].");
  m.def(
      "atmosphere_grid_wind",
      [](const AtmosphereParams& a, const py::handle& points) {
        py::array arr = checked_array(points, "points");
        auto p = as_float64(points, "points", {arr.ndim() == 2 ? arr.shape(0) : -1, 3});
        Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> out(p.shape(0), 3);
        for (py::ssize_t i = 0; i < p.shape(0); ++i) grid_wind(a, p.data() + 3 * i, out.data() + 3 * i);
        return out;
      },
      py::arg("params"), py::arg("points"), "The wind grid's trilinear wind at points (N, 3) [m], (N, 3) [m/s].");
  m.def(
      "validate_ground_effect", [](const GroundEffectParams& g) { return validate(g); }, py::arg("params"),
      "Empty string when the ground-effect constants give a finite gain in [1, 10] at every height, else a message.");

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
      .def_readwrite("ground_attitude", &QuadrotorParams::ground_attitude)
      .def_readwrite("max_integration_step", &QuadrotorParams::max_integration_step);

  m.def(
      "validate_params", [](const QuadrotorParams& p) { return validate(p); }, py::arg("params"),
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
      .def(py::init([](const py::handle& params, const py::handle& n_obj) {
             const QuadrotorParams& p = params_arg(params);
             std::int64_t n = 0;
             try {
               n = int_arg(n_obj, "n", 1, static_cast<std::int64_t>(QuadrotorBatch::kMaxSize));
             } catch (const py::value_error&) {
               throw py::value_error("n must be an integer in [1, 2^32], got " + std::string(py::repr(n_obj)));
             }
             return std::make_unique<QuadrotorBatch>(p, static_cast<std::size_t>(n));
           }),
           py::arg("params"), py::arg("n"))
      .def_property_readonly("size", &QuadrotorBatch::size)
      .def_property_readonly("params", &QuadrotorBatch::params, py::return_value_policy::copy,
                             "A copy of the parameters (they cannot change after construction).")
      .def_property(
          "time", &QuadrotorBatch::time,
          [](QuadrotorBatch& b, const py::handle& t) {
            if (!b.set_time(real_arg(t, "time"))) {
              throw py::value_error("time must be a finite number [s], got " + std::string(py::repr(t)));
            }
          },
          "Simulated time [s].")
      .def_property_readonly("hover_rotor_speed", &QuadrotorBatch::hover_rotor_speed)
      .def("reset", &QuadrotorBatch::reset,
           "All vehicles at the origin, level, at rest; time 0; rotor efficiency 1, rotor speed limit the "
           "parameters', floor z = 0 with a ground plane (else -inf), ceiling +inf. The ground effect stays.")
      .def_property_readonly(
          "rotor_efficiency",
          [](py::object self) { return readonly_view(self.cast<QuadrotorBatch&>(), QuadrotorBatch::kEta, 4, self); },
          "Per-rotor thrust and drag-torque scale in [0, 1], (N, 4) read-only view (set_rotor_efficiency).")
      .def(
          "set_rotor_efficiency",
          [](QuadrotorBatch& b, const py::handle& eta_obj) {
            auto eta = as_float64(eta_obj, "rotor_efficiency", {static_cast<py::ssize_t>(b.size()), kNumRotors});
            for (py::ssize_t k = 0; k < eta.size(); ++k) {
              const double e = eta.data()[k];
              if (!(e >= 0.0 && e <= 1.0)) {
                throw py::value_error("rotor_efficiency must be in [0, 1] (0: a stopped motor), got " +
                                      std::to_string(e) + " for vehicle " + std::to_string(k / kNumRotors) +
                                      ", rotor " + std::to_string(k % kNumRotors + 1));
              }
            }
            write_rows(b, QuadrotorBatch::kEta, kNumRotors, eta.data());
          },
          py::arg("eta"), "Sets the rotor efficiency, (N, 4) in [0, 1]; it persists across steps until reset().")
      .def_property_readonly(
          "max_rotor_speed",
          [](py::object self) {
            return readonly_view(self.cast<QuadrotorBatch&>(), QuadrotorBatch::kOmegaMax, 1, self);
          },
          "Upper clamp of the rotor speed command [rad/s], (N, 1) read-only view (set_max_rotor_speed).")
      .def(
          "set_max_rotor_speed",
          [](QuadrotorBatch& b, const py::handle& obj) {
            auto w = as_float64(obj, "max_rotor_speed", {static_cast<py::ssize_t>(b.size())});
            const double lo = b.params().rotor_speed_min;
            for (py::ssize_t k = 0; k < w.size(); ++k) {
              const double v = w.data()[k];
              if (!(std::isfinite(v) && v >= lo)) {
                throw py::value_error(
                    "max_rotor_speed must be a finite number >= rotor_speed_min = " + std::to_string(lo) +
                    " [rad/s], got " + std::to_string(v) + " for vehicle " + std::to_string(k));
              }
            }
            write_rows(b, QuadrotorBatch::kOmegaMax, 1, w.data());
          },
          py::arg("omega_max"), "Sets the rotor speed limit [rad/s], (N,); it persists across steps until reset().")
      .def_property_readonly(
          "surfaces_z",
          [](py::object self) { return readonly_view(self.cast<QuadrotorBatch&>(), QuadrotorBatch::kFloorZ, 2, self); },
          "Floor and ceiling heights [m] the ground effect reads, (N, 2) read-only view (-inf / +inf: none).")
      .def(
          "set_surfaces_z",
          [](QuadrotorBatch& b, const py::handle& obj) {
            auto s = as_float64(obj, "surfaces_z", {static_cast<py::ssize_t>(b.size()), 2});
            for (py::ssize_t i = 0; i < s.size() / 2; ++i) {
              const double f = s.data()[2 * i], c = s.data()[2 * i + 1];
              if (std::isnan(f) || std::isnan(c) || f == std::numeric_limits<double>::infinity() ||
                  c == -std::numeric_limits<double>::infinity() || f > c) {
                throw py::value_error(
                    "surfaces_z must be (floor_z, ceiling_z) [m] with floor_z <= ceiling_z "
                    "(-inf / +inf: none), got (" +
                    std::to_string(f) + ", " + std::to_string(c) + ") for vehicle " + std::to_string(i));
              }
            }
            write_rows(b, QuadrotorBatch::kFloorZ, 2, s.data());
          },
          py::arg("surfaces_z"), "Sets (floor_z, ceiling_z) per vehicle [m], (N, 2); held until changed or reset().")
      .def_property_readonly("has_atmosphere", &QuadrotorBatch::has_atmosphere)
      .def_property_readonly("atmosphere", &QuadrotorBatch::atmosphere, py::return_value_policy::copy,
                             "A copy of the atmosphere's constants.")
      .def(
          "set_atmosphere",
          [](QuadrotorBatch& b, const AtmosphereParams& a) {
            const std::string err = validate(a);
            if (!err.empty()) throw py::value_error(err);
            b.set_atmosphere(a);
          },
          py::arg("params"),
          "From the next step, the wind rows follow this atmosphere (updated once per its period); restarted by "
          "reset().")
      .def("clear_atmosphere", &QuadrotorBatch::clear_atmosphere, "No atmosphere: the wind rows are the caller's.")
      .def_property_readonly("ground_effect", &QuadrotorBatch::ground_effect, py::return_value_policy::copy,
                             "A copy of the ground-effect constants.")
      .def(
          "set_ground_effect",
          [](QuadrotorBatch& b, const GroundEffectParams& g) {
            if (g.enabled) {
              const std::string err = validate(g);
              if (!err.empty()) throw py::value_error(err);
            }
            b.set_ground_effect(g);
          },
          py::arg("params"), "Turns the ground and ceiling effect on (params.enabled) or off.")
#define CUFUND_VIEW(name, field, rows, doc)                                  \
  .def_property_readonly(                                                    \
      name,                                                                  \
      [](py::object self) {                                                  \
        auto& b = self.cast<QuadrotorBatch&>();                              \
        return soa_view(b.row(QuadrotorBatch::field), b.size(), rows, self); \
      },                                                                     \
      doc)
          CUFUND_VIEW("p", kP, 3, "Position p_W [m], (N, 3) view.") CUFUND_VIEW(
              "v", kV, 3, "Velocity v_W [m/s], (N, 3) view.") CUFUND_VIEW("q", kQ, 4,
                                                                          "Attitude q_WB [w, x, y, z], (N, 4) view.")
              CUFUND_VIEW("w", kW, 3, "Body rate w_B [rad/s], (N, 3) view.") CUFUND_VIEW(
                  "rotor_speeds", kRotor, 4, "Rotor speeds [rad/s], (N, 4) view, PX4 numbering.")
                  CUFUND_VIEW("wind_W", kWind, 3, "Wind velocity in world frame [m/s], (N, 3) view, held over a step.")
                      CUFUND_VIEW("force_ext_W", kForceExt, 3,
                                  "External force, world frame [N], (N, 3) view, held over a step.")
                          CUFUND_VIEW("torque_ext_B", kTorqueExt, 3,
                                      "External torque, body frame [N m], (N, 3) view, held over a step.")
                              CUFUND_VIEW("accel_W", kAccel, 3,
                                          "Acceleration dv_W/dt at the end of the last step [m/s^2], (N, 3) view.")
                                  CUFUND_VIEW(
                                      "alpha_B", kAlpha, 3,
                                      "Angular acceleration dw_B/dt at the end of the last step [rad/s^2], (N, 3).")
#undef CUFUND_VIEW
      .def(
          "step",
          [](QuadrotorBatch& b, const py::handle& dt_obj, const py::handle& cmd_obj, const py::handle& nthreads_obj) {
            const double dt = real_arg(dt_obj, "dt");
            const int nthreads = threads_arg(nthreads_obj);
            py::array_t<double, py::array::c_style> cmd = command_array(cmd_obj, b.size());
            StepResult r;
            // Release the GIL when the step is long: many vehicles or many sub-steps.
            const double work = static_cast<double>(b.size()) * (dt / b.params().max_integration_step);
            if (b.size() >= 64 || work >= 256.0) {
              py::gil_scoped_release release;
              r = b.step(dt, cmd.data(), nthreads);
            } else {
              r = b.step(dt, cmd.data(), nthreads);
            }
            raise_step_error(r, dt, cmd, b.size());
          },
          py::arg("dt"), py::arg("rotor_speed_cmd"), py::arg("nthreads") = 0,
          "Advance by dt [s] holding rotor_speed_cmd (N, 4) [rad/s]; nthreads 0 = all cores. Concurrent calls from "
          "several threads run one after the other (an internal lock).");
  m.def(
      "step_batches",
      [](const py::sequence& batches, const py::handle& dt_obj, const py::handle& cmd_obj,
         const py::handle& nthreads_obj) {
        const int nthreads = threads_arg(nthreads_obj);
        const auto n = static_cast<py::ssize_t>(py::len(batches));
        std::vector<BatchStep> steps(static_cast<std::size_t>(n));
        std::vector<py::ssize_t> first_row(static_cast<std::size_t>(n));
        // Own a reference to each batch for the call: a sequence's item may be made on access (or dropped from the
        // sequence while the GIL is released), and the raw pointers below must stay valid until the step is done.
        std::vector<py::object> held(static_cast<std::size_t>(n));
        py::ssize_t rows = 0;
        for (py::ssize_t k = 0; k < n; ++k) {
          held[k] = batches[k];
          py::handle b = held[k];
          if (!py::isinstance<QuadrotorBatch>(b)) {
            throw py::type_error("batches[" + std::to_string(k) + "] must be a QuadrotorBatch, got " + type_name(b));
          }
          steps[k].batch = &b.cast<QuadrotorBatch&>();
          for (py::ssize_t j = 0; j < k; ++j) {
            if (steps[j].batch == steps[k].batch) {
              throw py::value_error("batches must be distinct, got the same batch at " + std::to_string(j) + " and " +
                                    std::to_string(k));
            }
          }
          first_row[k] = rows;
          rows += static_cast<py::ssize_t>(steps[k].batch->size());
        }
        auto dt = as_float64(dt_obj, "dt", {n});
        auto cmd = as_float64(cmd_obj, "rotor_speed_cmd", {rows, kNumRotors});
        for (py::ssize_t k = 0; k < n; ++k) {
          steps[k].dt = dt.data()[k];
          steps[k].cmd = cmd.data() + first_row[k] * kNumRotors;
        }
        StepResult r;
        std::size_t failed = 0;
        {
          py::gil_scoped_release release;
          r = step_batches(steps.data(), steps.size(), nthreads, &failed);
        }
        if (r.status == StepStatus::kOk) return;
        const auto size = static_cast<py::ssize_t>(steps[failed].batch->size());
        py::array_t<double> own_cmd({size, static_cast<py::ssize_t>(kNumRotors)}, steps[failed].cmd);
        try {
          raise_step_error(r, steps[failed].dt, own_cmd, steps[failed].batch->size());
        } catch (const py::value_error& e) {
          throw py::value_error("batches[" + std::to_string(failed) + "]: " + e.what());
        }
      },
      py::arg("batches"), py::arg("dt"), py::arg("rotor_speed_cmd"), py::arg("nthreads") = 1,
      "Steps several QuadrotorBatch objects in one call (the GIL released): batches[k] by dt[k] (n,) [s] holding its "
      "rows of rotor_speed_cmd (sum of the sizes, 4) [rad/s] (the batches' rows one after the other), each exactly "
      "as batches[k].step(dt[k], its rows, 1) (bit for bit); nthreads threads over the batches (0 = all cores). "
      "Every batch is stepped; the first failure raises ValueError naming batches[k].");
  m.def(
      "set_max_step_substeps",
      [](const py::handle& n) { QuadrotorBatch::set_max_substeps(int_arg(n, "n", 1, 1000000000)); }, py::arg("n"),
      "Most RK4 sub-steps one QuadrotorBatch.step may take (process-wide).");
  m.def("max_step_substeps", &QuadrotorBatch::max_substeps, "Most RK4 sub-steps one QuadrotorBatch.step may take.");
}

}  // namespace cufund::py_bind

// --- Collisions of the vehicle's shape with static world meshes (Bullet) -------------------------
#include "collision_world.h"

namespace cufund::py_bind {

void define_collision(py::module_& m) {
  py::class_<CollisionWorld>(m, "CollisionWorld", R"doc(
Static world meshes and one vehicle shape (box or sphere) for collision checks with Bullet.
Use cufund.worlds.CollisionChecker, which builds it from a cufund.World.
)doc")
      .def(py::init<>())
      .def(
          "add_mesh",
          [](CollisionWorld& w, const py::handle& vertices, const py::handle& triangles) {
            py::array v_arr = py::array::ensure(vertices);
            if (!v_arr || v_arr.ndim() != 2 || v_arr.shape(1) != 3) {
              throw py::value_error("vertices must have shape (V, 3), got " +
                                    (v_arr ? shape_str(v_arr) : std::string("a non-array")));
            }
            auto v = as_float64(vertices, "vertices", {v_arr.shape(0), 3});
            py::array t_arr = py::array::ensure(triangles);
            if (!t_arr || t_arr.ndim() != 2 || t_arr.shape(1) != 3 || t_arr.shape(0) == 0 ||
                (t_arr.dtype().kind() != 'i' && t_arr.dtype().kind() != 'u')) {
              throw py::value_error("triangles must be an integer array of shape (T, 3) with T >= 1, got " +
                                    (t_arr ? shape_str(t_arr) : std::string("a non-array")));
            }
            auto t64 = contiguous<std::int64_t>(t_arr, "triangles");
            const auto nv = static_cast<std::int64_t>(v.shape(0));
            std::vector<std::uint32_t> tri(static_cast<std::size_t>(t64.size()));
            for (py::ssize_t i = 0; i < t64.size(); ++i) {
              const std::int64_t k = t64.data()[i];
              if (k < 0 || k >= nv) {
                throw py::value_error("triangles must index vertices in [0, " + std::to_string(nv) + "), got " +
                                      std::to_string(k) + " in triangle " + std::to_string(i / 3));
              }
              tri[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(k);
            }
            for (py::ssize_t i = 0; i < v.size(); ++i) {
              if (!std::isfinite(v.data()[i])) throw py::value_error("vertices must be finite");
            }
            return w.add_mesh(v.data(), static_cast<std::size_t>(nv), tri.data(), tri.size() / 3);
          },
          py::arg("vertices"), py::arg("triangles"), "Adds a static mesh [m]; returns its object id (0, 1, ...).")
      .def(
          "set_vehicle_box",
          [](CollisionWorld& w, const py::handle& half_extents) {
            auto h = as_float64(half_extents, "half_extents", {3});
            for (int k = 0; k < 3; ++k) {
              if (!(std::isfinite(h.data()[k]) && h.data()[k] > 0)) {
                throw py::value_error("box half extents must be 3 finite numbers > 0 [m] (box_size / 2)");
              }
            }
            w.set_vehicle_box(h.data()[0], h.data()[1], h.data()[2]);
          },
          py::arg("half_extents"), "The vehicle is a box of half extents (hx, hy, hz) [m] about the body origin.")
      .def(
          "set_vehicle_sphere",
          [](CollisionWorld& w, const py::handle& radius_obj) {
            const double radius = real_arg(radius_obj, "radius");
            if (!(std::isfinite(radius) && radius > 0)) {
              throw py::value_error("radius must be a finite number > 0 [m], got " + std::to_string(radius));
            }
            w.set_vehicle_sphere(radius);
          },
          py::arg("radius"), "The vehicle is a sphere of this radius [m] about the body origin.")
      .def(
          "check",
          [](const CollisionWorld& w, const py::handle& p_W, const py::handle& q_WB,
             const py::handle& margin_obj) -> py::object {
            const double margin = real_arg(margin_obj, "margin");
            auto p = as_float64(p_W, "p_W", {3});
            auto q = as_float64(q_WB, "q_WB", {4});
            double qn = 0;
            for (int k = 0; k < 4; ++k) qn += q.data()[k] * q.data()[k];
            for (int k = 0; k < 3; ++k) {
              if (!std::isfinite(p.data()[k])) throw py::value_error("p_W must be finite [m]");
            }
            if (!(std::isfinite(qn) && qn > 1e-12)) throw py::value_error("q_WB must be a finite non-zero quaternion");
            if (!(std::isfinite(margin) && margin >= 0))
              throw py::value_error("margin must be a finite number >= 0 [m]");
            double qu[4];
            for (int k = 0; k < 4; ++k) qu[k] = q.data()[k] / std::sqrt(qn);
            const Contact c = w.check(p.data(), qu, margin);
            if (!c.hit) return py::none();
            py::dict d;
            d["object_id"] = c.object_id;
            d["point_W"] = Eigen::Vector3d(c.point_W[0], c.point_W[1], c.point_W[2]);
            d["normal_W"] = Eigen::Vector3d(c.normal_W[0], c.normal_W[1], c.normal_W[2]);
            d["distance"] = c.distance;
            return std::move(d);
          },
          py::arg("p_W"), py::arg("q_WB"), py::arg("margin") = 0.0, R"doc(
The deepest contact of the vehicle at body pose (p_W [m], q_WB [w, x, y, z]) with any mesh whose
signed distance is <= margin [m], as a dict (object_id, point_W on the mesh, normal_W from the mesh
towards the vehicle, distance: negative = penetration), or None.
)doc")
      .def_property_readonly("num_objects", &CollisionWorld::num_objects);
}

}  // namespace cufund::py_bind
