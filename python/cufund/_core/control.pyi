"""
Control allocation and the SE(3) attitude law (paper §2.3).
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['ControlAllocator', 'attitude_from_thrust_and_yaw', 'geometric_from_attitude', 'geometric_from_force']
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
