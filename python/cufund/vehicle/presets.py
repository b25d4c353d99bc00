"""Vehicle presets. Every number carries its source, or says how it was chosen."""

from __future__ import annotations

import math

from .params import QuadrotorParams

__all__ = ["crazyflie", "iris", "cu_astro"]


def crazyflie() -> QuadrotorParams:
    """Bitcraze Crazyflie 2.x, with exactly the numbers of RotorPy 3.0.0's ``crazyflie_params.py``.

    RotorPy cites Forster, "System Identification of the Crazyflie 2.0 Nano Quadrocopter" (ETH, 2015)
    for inertia, thrust and moment coefficients, and Eschmann et al. 2024 (arXiv:2404.07837) for the
    motor delay. RotorPy's rotor order (front-left, front-right, rear-right, rear-left) maps onto PX4
    quad-x numbering as rotor 3, 1, 4, 2. Body drag is zero there, and here.
    """
    k_eta = 2.3e-08  # thrust coefficient [N/(rad/s)^2]
    k_m = 7.8e-10  # yaw moment coefficient [N m/(rad/s)^2]
    return QuadrotorParams(
        name="crazyflie",
        mass=0.03,
        inertia=((1.43e-5, 0.0, 0.0), (0.0, 1.43e-5, 0.0), (0.0, 0.0, 2.89e-5)),
        arm_length=0.043,
        layout="x",
        k_f=k_eta,
        c_m=k_m / k_eta,
        tau_m=0.072,
        rotor_speed_min=0.0,
        rotor_speed_max=2500.0,
        rotor_drag_xy=10.2506e-07,
        rotor_drag_z=7.553e-07,
        body_drag=(0.0, 0.0, 0.0),
    )


def iris() -> QuadrotorParams:
    """3DR Iris as simulated by PX4 SITL (PX4-SITL_gazebo-classic ``models/iris/iris.sdf``).

    From the SDF: base_link mass 1.5 kg and inertia diag(0.029125, 0.029125, 0.055225) kg m^2;
    motorConstant 5.84e-06 N/(rad/s)^2 (k_f); momentConstant 0.06 m (c_m); timeConstantUp 0.0125 s
    (tau_m; the SDF's slower spin-down, 0.025 s, is not modelled); maxRotVelocity 1100 rad/s;
    rotorDragCoefficient 1.75e-04 kg/rad (rotor drag in the rotor plane). The SDF's rotors sit at
    (+-0.13, +-0.22) m; the symmetric quad-x model here uses the same centre distance,
    d = sqrt(0.13^2 + 0.22^2) = 0.2555 m, at 45 degrees.
    """
    return QuadrotorParams(
        name="iris",
        mass=1.5,
        inertia=((0.029125, 0.0, 0.0), (0.0, 0.029125, 0.0), (0.0, 0.0, 0.055225)),
        arm_length=math.hypot(0.13, 0.22),
        layout="x",
        k_f=5.84e-06,
        c_m=0.06,
        tau_m=0.0125,
        rotor_speed_min=0.0,
        rotor_speed_max=1100.0,
        rotor_drag_xy=1.75e-04,
        rotor_drag_z=0.0,
    )


def cu_astro() -> QuadrotorParams:
    """A small LiDAR quadrotor resembling the paper's CU-Astro (§3: 216 x 216 x 95 mm, Livox Mid-360).

    The paper gives only the size, so the rest is an engineering estimate, stated here:

    - Mass 0.80 kg: Mid-360 (265 g, Livox datasheet) + onboard computer (~100 g) + 4S 850 mAh battery
      (~100 g) + frame, four 1404-class motors, ESC and flight controller (~335 g).
    - Inertia: a uniform 0.216 x 0.216 x 0.095 m box of 0.80 kg, I_xx = I_yy = m (a^2 + h^2) / 12,
      I_zz = m (2 a^2) / 12; an upper bound for a vehicle whose mass sits near its centre.
    - 3-inch (76 mm) propellers inside the 216 mm footprint put the motor centres 70 mm from each
      axis: d = 0.070 * sqrt(2) = 0.099 m, quad-x.
    - k_f = 4.97e-7 N/(rad/s)^2: ~4.9 N static thrust per 3-inch propeller at 3140 rad/s (30 000 rpm),
      a thrust-to-weight ratio of 2.5; hover at ~1990 rad/s; rotor_speed_max 3140 rad/s.
    - c_m = 0.0125 m and tau_m = 0.03 s: typical of small propellers and brushless motors.
    - Body drag 0.5 * rho * C_d * A with rho = 1.225 kg/m^3, C_d = 1, A the box's side (0.216 x 0.095 m)
      and top (0.216 x 0.216 m) faces.
    """
    a, h, m = 0.216, 0.095, 0.80
    ixx = m * (a * a + h * h) / 12.0
    izz = m * (2.0 * a * a) / 12.0
    rho = 1.225
    return QuadrotorParams(
        name="cu_astro",
        mass=m,
        inertia=((ixx, 0.0, 0.0), (0.0, ixx, 0.0), (0.0, 0.0, izz)),
        arm_length=0.070 * math.sqrt(2.0),
        layout="x",
        k_f=4.97e-7,
        c_m=0.0125,
        tau_m=0.03,
        rotor_speed_min=0.0,
        rotor_speed_max=3140.0,
        body_drag=(0.5 * rho * a * h, 0.5 * rho * a * h, 0.5 * rho * a * a),
    )
