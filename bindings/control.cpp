// Bindings for cpp/control: control allocation and the SE(3) geometric controller's attitude law.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>

#include "allocation.h"
#include "geometric_control.h"
#include "pybind_common.h"

namespace cufund::py_bind {
namespace {

// A finite (N,) vector, else ValueError naming the field.
template <int N>
Eigen::Matrix<double, N, 1> finite_vector(const py::handle& obj, const char* field) {
  auto a = as_float64(obj, field, {N});
  const Eigen::Map<const Eigen::Matrix<double, N, 1>> v(a.data());
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

// A finite, non-zero quaternion [w, x, y, z], normalised (left bit-identical when already unit).
Eigen::Vector4d unit_quaternion(const py::handle& obj, const char* field) {
  const Eigen::Vector4d q = vec4(obj, field);
  const double norm = q.norm();
  if (!(norm >= 1e-6)) {
    throw py::value_error(std::string(field) + " must be a non-zero quaternion [w, x, y, z], got norm " +
                          std::to_string(norm));
  }
  return std::abs(norm - 1.0) <= 1e-12 ? q : Eigen::Vector4d(q / norm);
}

py::tuple command_tuple(const GeometricAttitudeCommand& c) {
  return py::make_tuple(c.thrust, Eigen::Vector3d(c.torque_B), Eigen::Vector4d(c.q_WB_d));
}

}  // namespace

void define_control(py::module_& m) {
  py::class_<ControlAllocator>(m, "ControlAllocator",
                               "Prioritising allocation: roll/pitch first, then collective thrust, then yaw.")
      .def(py::init([](const py::handle& params) {
             if (!py::isinstance<QuadrotorParams>(params)) {
               throw py::type_error("params must be a cufund.QuadrotorParams (its .to_core()), got " + type_name(params));
             }
             const QuadrotorParams& p = params.cast<const QuadrotorParams&>();
             const std::string err = validate(p);
             if (!err.empty()) throw py::value_error(err);
             return ControlAllocator(p);
           }),
           py::arg("params"))
      .def("allocate",
           [](const ControlAllocator& a, const py::handle& thrust, const py::handle& torque_B) {
             const AllocationResult r = a.allocate(finite(thrust, "thrust"), vec3(torque_B, "torque_B"));
             return py::make_tuple(Eigen::Vector4d(r.rotor_speeds), Eigen::Vector4d(r.achieved),
                                   py::make_tuple(r.saturation[0], r.saturation[1], r.saturation[2],
                                                  r.saturation[3]));
           },
           py::arg("thrust"), py::arg("torque_B"),
           "(rotor_speeds (4,) [rad/s], achieved [f, Mx, My, Mz] (4,), saturation signs (4 ints)).")
      .def_property_readonly("max_thrust", &ControlAllocator::max_thrust, "All rotors at full speed [N].");

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
                                                  vec3(j_W, "j_W"), finite(yaw, "yaw"),
                                                  finite(yaw_rate, "yaw_rate")));
      },
      py::arg("J"), py::arg("mass"), py::arg("k_R"), py::arg("k_W"), py::arg("q_WB"), py::arg("w_B"), py::arg("F_W"),
      py::arg("j_W"), py::arg("yaw"), py::arg("yaw_rate"),
      "Lee et al.'s attitude law from a desired world force: (thrust [N], torque_B (3,) [N m], q_WB_d (4,)).");
  m.def(
      "geometric_from_attitude",
      [](const py::handle& J, const py::handle& k_R, const py::handle& k_W, const py::handle& q_WB,
         const py::handle& w_B, const py::handle& q_WB_d, const py::handle& thrust, const py::handle& yaw_rate) {
        const Eigen::Matrix3d Jm = inertia_arg(J);
        return command_tuple(geometric_from_attitude(Jm, vec3(k_R, "k_R"), vec3(k_W, "k_W"),
                                                     unit_quaternion(q_WB, "q_WB"), vec3(w_B, "w_B"),
                                                     unit_quaternion(q_WB_d, "q_WB_d"),
                                                     finite(thrust, "thrust"), finite(yaw_rate, "yaw_rate")));
      },
      py::arg("J"), py::arg("k_R"), py::arg("k_W"), py::arg("q_WB"), py::arg("w_B"), py::arg("q_WB_d"),
      py::arg("thrust"), py::arg("yaw_rate"),
      "Lee et al.'s attitude law for a desired attitude and thrust: (thrust, torque_B (3,), q_WB_d (4,)).");
}

}  // namespace cufund::py_bind
