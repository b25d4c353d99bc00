"""
Control allocation and the SE(3) attitude law (paper §2.3).
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['AttitudeControl', 'ControlAllocator', 'GeometricControl', 'PositionControl', 'RateControl', 'attitude_from_thrust_and_yaw', 'geometric_from_attitude', 'geometric_from_force']
class ControlAllocator:
    """
    Prioritising allocation: roll/pitch first, then collective thrust, then yaw.
    """
    def __init__(self, params: typing.Any) -> None:
        ...
    def allocate(self, thrust: typing.Any, torque_B: typing.Any) -> tuple[typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 1]"], typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 1]"], tuple[int, int, int, int]]:
        """
        (rotor_speeds (4,) [rad/s], achieved [f, Mx, My, Mz] (4,), saturation signs (4 ints)).
        """
    @property
    def max_thrust(self) -> float:
        """
        All rotors at full speed [N].
        """
class PositionControl:
    """
    The arithmetic of one PX4-style position-control step (cufund.control.PositionController keeps the flight-mode logic): position P -> velocity PID -> limited thrust vector -> attitude setpoint.
    """
    def __init__(self, mass: typing.Any, gravity: typing.Any, max_thrust: typing.Any, vel_d_cutoff_hz: typing.Any, transfer_tau: typing.Any) -> None:
        """
        mass [kg], gravity [m/s^2], max_thrust [N], the velocity derivative's low-pass cutoff [Hz] (0: none), the mode-switch hand-over's decay time [s].
        """
    def filter_velocity(self, v_W: typing.Any, dt: typing.Any) -> None:
        """
        Steps the measured velocity's derivative filter only (attitude mode).
        """
    def reset(self) -> None:
        """
        Integrator, derivative filter and hand-over to their initial state.
        """
    def set_gains(self, k_p: typing.Any, k_v: typing.Any, k_i: typing.Any, k_d: typing.Any, xy_vel_max: typing.Any, z_vel_max_up: typing.Any, z_vel_max_dn: typing.Any, tilt_max: typing.Any, thr_min: typing.Any, thr_max: typing.Any) -> None:
        """
        Gains (x, y, z) and limits as in cufund.control.PositionControlParams.
        """
    def step(self, t: typing.Any, dt: typing.Any, p_W: typing.Any, v_W: typing.Any, p_sp: typing.Any, v_sp: typing.Any, a_sp: typing.Any, yaw: typing.Any, position_mode: typing.Any, handover: typing.Any = None) -> tuple[numpy.typing.NDArray[numpy.float64], float]:
        """
        One step at t [s], dt [s] after the last: (q_WB setpoint (4,) read-only, thrust [N]). position_mode False tracks v_sp only; handover (3,) [m/s^2], at a mode switch, is the acceleration last commanded.
        """
    @property
    def acc_filt(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 1]"]:
        """
        Low-passed measured acceleration (3,) [m/s^2] that D acts on.
        """
    @property
    def vel_int(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 1]"]:
        """
        Velocity integrator (3,) [m/s^2].
        """
    @vel_int.setter
    def vel_int(self, arg1: typing.Any) -> None:
        ...
class AttitudeControl:
    """
    PX4-style attitude P with reduced yaw priority: attitude error -> body-rate setpoint.
    """
    def __init__(self) -> None:
        ...
    def rate_setpoint(self, q_WB: typing.Any, q_WB_d: typing.Any, yaw_rate: typing.Any) -> numpy.typing.NDArray[numpy.float64]:
        """
        Body-rate setpoint (3,) [rad/s], read-only, for attitude q_WB towards q_WB_d with the yaw-rate feed-forward [rad/s] about world z.
        """
    def set_gains(self, k: typing.Any, rate_max: typing.Any, yaw_weight: typing.Any) -> None:
        """
        Gains (roll, pitch, their mean) [1/s], rate limits (3,) [rad/s], yaw weight in [0, 1].
        """
class RateControl:
    """
    One PX4-style body-rate PID step with prioritising allocation to rotor speeds.
    """
    def __init__(self, params: typing.Any, d_cutoff_hz: typing.Any, i_scale: typing.Any) -> None:
        """
        params: a cufund.QuadrotorParams (its .to_core()); the rate derivative's low-pass cutoff [Hz] (0: none); i_scale [rad/s]: the rate error at which the integrator stops growing.
        """
    def reset(self) -> None:
        """
        Integrator and derivative filter to their initial state.
        """
    def set_gains(self, k_p: typing.Any, k_i: typing.Any, k_d: typing.Any, feed_forward: typing.Any, integrator_limit: typing.Any) -> None:
        """
        Gains (roll, pitch, yaw) as in cufund.control.RateControlParams.
        """
    def step(self, w_B: typing.Any, w_sp: typing.Any, thrust: typing.Any, dt: typing.Any) -> tuple[numpy.typing.NDArray[numpy.float64], float, numpy.typing.NDArray[numpy.float64], tuple[int, int, int, int]]:
        """
        One step with measured rate w_B (3,) [rad/s], setpoint w_sp (3,) [rad/s], collective thrust [N], dt [s] after the last: (rotor_speeds (4,) [rad/s], achieved thrust [N], achieved torque_B (3,) [N m], saturation signs of [f, Mx, My, Mz]); arrays read-only.
        """
    @property
    def rate_int(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 1]"]:
        """
        Rate integrator (3,) [rad/s^2].
        """
    @rate_int.setter
    def rate_int(self, arg1: typing.Any) -> None:
        ...
class GeometricControl:
    """
    The SE(3) controller's force law, attitude law and allocation, one call per step (cufund.control.GeometricController keeps the flight-mode logic).
    """
    def __init__(self, params: typing.Any, transfer_tau: typing.Any) -> None:
        """
        params: a cufund.QuadrotorParams (its .to_core()); the mode-switch hand-over's decay time [s].
        """
    def reset(self) -> None:
        """
        Clears the mode-switch hand-over.
        """
    def set_gains(self, k_x: typing.Any, k_v: typing.Any, k_R: typing.Any, k_W: typing.Any) -> None:
        """
        k_x [m/s^2 per m], k_v [m/s^2 per m/s], k_R (3,) [rad/s^2 per rad], k_W (3,) [rad/s^2 per rad/s].
        """
    def step_attitude(self, q_WB: typing.Any, w_B: typing.Any, q_WB_d: typing.Any, thrust: typing.Any, yaw_rate: typing.Any) -> tuple:
        """
        Attitude mode: as step_force's result for a desired attitude q_WB_d, thrust [N] and yaw rate [rad/s].
        """
    def step_force(self, t: typing.Any, p_W: typing.Any, v_W: typing.Any, q_WB: typing.Any, w_B: typing.Any, p_sp: typing.Any, v_sp: typing.Any, a_sp: typing.Any, j_sp: typing.Any, yaw: typing.Any, yaw_rate: typing.Any, position_mode: typing.Any, handover: typing.Any = None) -> tuple:
        """
        Position (or, position_mode False, velocity) mode at t [s]; handover (3,) [N], at a mode switch, is the force last commanded. (q_WB_d (4,), thrust [N], rotor_speeds (4,) [rad/s], achieved thrust [N], achieved torque_B (3,) [N m]), arrays read-only.
        """
def attitude_from_thrust_and_yaw(z_B: typing.Any, yaw: typing.Any) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 3]"]:
    """
    R_WB (3, 3) with body z along unit z_B and body x along the heading yaw, projected (PX4's bodyzToAttitude).
    """
def geometric_from_attitude(J: typing.Any, k_R: typing.Any, k_W: typing.Any, q_WB: typing.Any, w_B: typing.Any, q_WB_d: typing.Any, thrust: typing.Any, yaw_rate: typing.Any) -> tuple:
    """
    Lee et al.'s attitude law for a desired attitude and thrust: (thrust, torque_B (3,), q_WB_d (4,)).
    """
def geometric_from_force(J: typing.Any, mass: typing.Any, k_R: typing.Any, k_W: typing.Any, q_WB: typing.Any, w_B: typing.Any, F_W: typing.Any, j_W: typing.Any, yaw: typing.Any, yaw_rate: typing.Any) -> tuple:
    """
    Lee et al.'s attitude law from a desired world force: (thrust [N], torque_B (3,) [N m], q_WB_d (4,)).
    """
