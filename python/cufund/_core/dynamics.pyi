"""
Quadrotor rigid-body dynamics (paper §2.1).
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['CollisionWorld', 'QuadrotorBatch', 'QuadrotorParams', 'RotorLayout', 'allocation_matrix', 'allocation_matrix_inverse', 'max_step_substeps', 'rotor_positions', 'rotor_spins', 'set_max_step_substeps', 'validate_params']
class RotorLayout:
    """
    Rotor arrangement and numbering (PX4 airframe reference).
    
    Members:
    
      PLUS : 1 front, 2 right, 3 back, 4 left; 1 and 3 clockwise
    
      X : PX4 quad-x: 1 front-right, 2 rear-left, 3 front-left, 4 rear-right; 1, 2 CCW
    """
    PLUS: typing.ClassVar[RotorLayout]
    X: typing.ClassVar[RotorLayout]
    __members__: typing.ClassVar[dict[str, RotorLayout]]
    @typing.overload
    def __eq__(self, other: RotorLayout) -> bool:
        ...
    @typing.overload
    def __eq__(self, other: typing.Any) -> bool:
        ...
    def __getstate__(self) -> int:
        ...
    def __hash__(self) -> int:
        ...
    def __index__(self) -> int:
        ...
    def __init__(self, value: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    def __int__(self) -> int:
        ...
    @typing.overload
    def __ne__(self, other: RotorLayout) -> bool:
        ...
    @typing.overload
    def __ne__(self, other: typing.Any) -> bool:
        ...
    def __repr__(self) -> str:
        ...
    def __setstate__(self, state: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    def __str__(self) -> str:
        ...
    @property
    def name(self) -> str:
        ...
    @property
    def value(self) -> int:
        ...
class QuadrotorParams:
    """
    Plain C++ parameter record; use cufund.QuadrotorParams, which validates and documents.
    """
    ground_plane: bool
    layout: RotorLayout
    def __init__(self) -> None:
        ...
    @property
    def arm_length(self) -> float:
        ...
    @arm_length.setter
    def arm_length(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def body_drag(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 1]"]:
        ...
    @body_drag.setter
    def body_drag(self, arg0: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[3, 1]"]) -> None:
        ...
    @property
    def c_m(self) -> float:
        ...
    @c_m.setter
    def c_m(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gravity(self) -> float:
        ...
    @gravity.setter
    def gravity(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def ground_attitude(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 1]"]:
        ...
    @ground_attitude.setter
    def ground_attitude(self, arg0: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[4, 1]"]) -> None:
        ...
    @property
    def inertia(self) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 3]"]:
        ...
    @inertia.setter
    def inertia(self, arg0: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[3, 3]"]) -> None:
        ...
    @property
    def k_f(self) -> float:
        ...
    @k_f.setter
    def k_f(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def mass(self) -> float:
        ...
    @mass.setter
    def mass(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def max_integration_step(self) -> float:
        ...
    @max_integration_step.setter
    def max_integration_step(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_drag_xy(self) -> float:
        ...
    @rotor_drag_xy.setter
    def rotor_drag_xy(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_drag_z(self) -> float:
        ...
    @rotor_drag_z.setter
    def rotor_drag_z(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_speed_max(self) -> float:
        ...
    @rotor_speed_max.setter
    def rotor_speed_max(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_speed_min(self) -> float:
        ...
    @rotor_speed_min.setter
    def rotor_speed_min(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def tau_m(self) -> float:
        ...
    @tau_m.setter
    def tau_m(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
class QuadrotorBatch:
    """
    N quadrotors integrated together; state arrays are views into C++ memory.
    """
    def __init__(self, params: typing.Any, n: typing.Any) -> None:
        ...
    def reset(self) -> None:
        """
        All vehicles at the origin, level, at rest; time 0.
        """
    def step(self, dt: typing.Any, rotor_speed_cmd: typing.Any, nthreads: typing.Any = 0) -> None:
        """
        Advance by dt [s] holding rotor_speed_cmd (N, 4) [rad/s]; nthreads 0 = all cores. Concurrent calls from several threads run one after the other (an internal lock).
        """
    @property
    def accel_W(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Acceleration dv_W/dt at the end of the last step [m/s^2], (N, 3) view.
        """
    @property
    def alpha_B(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Angular acceleration dw_B/dt at the end of the last step [rad/s^2], (N, 3).
        """
    @property
    def force_ext_W(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        External force, world frame [N], (N, 3) view, held over a step.
        """
    @property
    def hover_rotor_speed(self) -> float:
        ...
    @property
    def p(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Position p_W [m], (N, 3) view.
        """
    @property
    def params(self) -> QuadrotorParams:
        """
        A copy of the parameters (they cannot change after construction).
        """
    @property
    def q(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Attitude q_WB [w, x, y, z], (N, 4) view.
        """
    @property
    def rotor_speeds(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Rotor speeds [rad/s], (N, 4) view, PX4 numbering.
        """
    @property
    def size(self) -> int:
        ...
    @property
    def time(self) -> float:
        """
        Simulated time [s].
        """
    @time.setter
    def time(self, arg1: typing.Any) -> None:
        ...
    @property
    def torque_ext_B(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        External torque, body frame [N m], (N, 3) view, held over a step.
        """
    @property
    def v(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Velocity v_W [m/s], (N, 3) view.
        """
    @property
    def w(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Body rate w_B [rad/s], (N, 3) view.
        """
    @property
    def wind_W(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Wind velocity in world frame [m/s], (N, 3) view, held over a step.
        """
class CollisionWorld:
    """
    Static world meshes and one vehicle shape (box or sphere) for collision checks with Bullet.
    Use cufund.worlds.CollisionChecker, which builds it from a cufund.World.
    """
    def __init__(self) -> None:
        ...
    def add_mesh(self, vertices: typing.Any, triangles: typing.Any) -> int:
        """
        Adds a static mesh [m]; returns its object id (0, 1, ...).
        """
    def check(self, p_W: typing.Any, q_WB: typing.Any, margin: typing.Any = 0.0) -> typing.Any:
        """
        The deepest contact of the vehicle at body pose (p_W [m], q_WB [w, x, y, z]) with any mesh whose
        signed distance is <= margin [m], as a dict (object_id, point_W on the mesh, normal_W from the mesh
        towards the vehicle, distance: negative = penetration), or None.
        """
    def set_vehicle_box(self, half_extents: typing.Any) -> None:
        """
        The vehicle is a box of half extents (hx, hy, hz) [m] about the body origin.
        """
    def set_vehicle_sphere(self, radius: typing.Any) -> None:
        """
        The vehicle is a sphere of this radius [m] about the body origin.
        """
    @property
    def num_objects(self) -> int:
        ...
def allocation_matrix(params: QuadrotorParams) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 4]"]:
    """
    A (4, 4): rotor thrusts [N] -> [f, M_x, M_y, M_z] in body FLU (paper eq. 1).
    """
def allocation_matrix_inverse(params: QuadrotorParams) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 4]"]:
    """
    A^-1 (4, 4): [f, M_x, M_y, M_z] -> rotor thrusts [N], unsaturated.
    """
def max_step_substeps() -> int:
    """
    Most RK4 sub-steps one QuadrotorBatch.step may take.
    """
def rotor_positions(params: QuadrotorParams) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 3]"]:
    """
    Rotor centres in body FLU [m], shape (4, 3), PX4 numbering.
    """
def rotor_spins(params: QuadrotorParams) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[4, 1]"]:
    """
    +1 for a rotor spinning counter-clockwise seen from above, -1 clockwise.
    """
def set_max_step_substeps(n: typing.Any) -> None:
    """
    Most RK4 sub-steps one QuadrotorBatch.step may take (process-wide).
    """
def validate_params(params: QuadrotorParams) -> str:
    """
    Empty string when the parameters are physical, else a message naming the field.
    """
