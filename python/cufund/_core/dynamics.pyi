"""
Quadrotor rigid-body dynamics (paper §2.1).
"""
from __future__ import annotations
import collections.abc
import numpy
import numpy.typing
import typing
__all__: list[str] = ['AtmosphereParams', 'CollisionWorld', 'GroundEffectParams', 'GustEvent', 'QuadrotorBatch', 'QuadrotorParams', 'RotorLayout', 'WindShear', 'allocation_matrix', 'allocation_matrix_inverse', 'atmosphere_grid_wind', 'dryden_scales', 'max_step_substeps', 'rotor_positions', 'rotor_spins', 'set_max_step_substeps', 'step_batches', 'validate_atmosphere', 'validate_ground_effect', 'validate_params']
class GroundEffectParams:
    """
    Ground and ceiling effect constants (cpp/dynamics/ground_effect.h); use cufund.vehicle.ground_effect.GroundEffectConfig.
    """
    enabled: bool
    def __init__(self) -> None:
        ...
    @property
    def body_distance(self) -> float:
        ...
    @body_distance.setter
    def body_distance(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def ceiling_k1(self) -> float:
        ...
    @ceiling_k1.setter
    def ceiling_k1(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def ceiling_k2(self) -> float:
        ...
    @ceiling_k2.setter
    def ceiling_k2(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def k_body(self) -> float:
        ...
    @k_body.setter
    def k_body(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def min_height(self) -> float:
        ...
    @min_height.setter
    def min_height(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_plane_height(self) -> float:
        ...
    @rotor_plane_height.setter
    def rotor_plane_height(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_radius(self) -> float:
        ...
    @rotor_radius.setter
    def rotor_radius(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rotor_spacing(self) -> float:
        ...
    @rotor_spacing.setter
    def rotor_spacing(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
class WindShear:
    """
    Mean wind profile with height.
    
    Members:
    
      NONE
    
      LOG
    
      POWER
    """
    LOG: typing.ClassVar[WindShear]
    NONE: typing.ClassVar[WindShear]
    POWER: typing.ClassVar[WindShear]
    __members__: typing.ClassVar[dict[str, WindShear]]
    @typing.overload
    def __eq__(self, other: WindShear) -> bool:
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
    def __ne__(self, other: WindShear) -> bool:
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
class GustEvent:
    """
    A 1-cosine gust; use cufund.worlds.gusts.GustConfig.
    """
    def __getstate__(self) -> tuple[float, float, float, float]:
        ...
    def __init__(self) -> None:
        ...
    def __setstate__(self, arg0: tuple) -> None:
        ...
    @property
    def amplitude(self) -> float:
        ...
    @amplitude.setter
    def amplitude(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def direction(self) -> float:
        ...
    @direction.setter
    def direction(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def duration(self) -> float:
        ...
    @duration.setter
    def duration(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def t_start(self) -> float:
        ...
    @t_start.setter
    def t_start(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
class AtmosphereParams:
    """
    The atmosphere's constants (cpp/dynamics/atmosphere.h); use cufund.worlds.atmosphere.AtmosphereConfig.
    """
    shear: WindShear
    turbulence: bool
    def __getstate__(self) -> tuple[float, float, bool, int, float, float, float, float, int, list[GustEvent], list[float], list[float], list[float], list[float]]:
        ...
    def __init__(self) -> None:
        ...
    def __setstate__(self, arg0: tuple) -> None:
        ...
    def set_grid(self, x: typing.Any, y: typing.Any, z: typing.Any, wind: typing.Any) -> None:
        """
        Sets the wind grid: axes x (nx,), y (ny,), z (nz,) [m], wind (nx, ny, nz, 3) [m/s].
        """
    @property
    def direction(self) -> float:
        ...
    @direction.setter
    def direction(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gusts(self) -> list[GustEvent]:
        ...
    @gusts.setter
    def gusts(self, arg0: collections.abc.Sequence[GustEvent]) -> None:
        ...
    @property
    def has_grid(self) -> bool:
        ...
    @property
    def min_airspeed(self) -> float:
        ...
    @min_airspeed.setter
    def min_airspeed(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def roughness_z0(self) -> float:
        ...
    @roughness_z0.setter
    def roughness_z0(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def seed(self) -> int:
        ...
    @seed.setter
    def seed(self, arg0: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def shear_exponent(self) -> float:
        ...
    @shear_exponent.setter
    def shear_exponent(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def update_period(self) -> float:
        ...
    @update_period.setter
    def update_period(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def wind_20ft(self) -> float:
        ...
    @wind_20ft.setter
    def wind_20ft(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
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
    def clear_atmosphere(self) -> None:
        """
        No atmosphere: the wind rows are the caller's.
        """
    def reset(self) -> None:
        """
        All vehicles at the origin, level, at rest; time 0; rotor efficiency 1, rotor speed limit the parameters', floor z = 0 with a ground plane (else -inf), ceiling +inf. The ground effect stays.
        """
    def set_atmosphere(self, params: AtmosphereParams) -> None:
        """
        From the next step, the wind rows follow this atmosphere (updated once per its period); restarted by reset().
        """
    def set_ground_effect(self, params: GroundEffectParams) -> None:
        """
        Turns the ground and ceiling effect on (params.enabled) or off.
        """
    def set_max_rotor_speed(self, omega_max: typing.Any) -> None:
        """
        Sets the rotor speed limit [rad/s], (N,); it persists across steps until reset().
        """
    def set_rotor_efficiency(self, eta: typing.Any) -> None:
        """
        Sets the rotor efficiency, (N, 4) in [0, 1]; it persists across steps until reset().
        """
    def set_surfaces_z(self, surfaces_z: typing.Any) -> None:
        """
        Sets (floor_z, ceiling_z) per vehicle [m], (N, 2); held until changed or reset().
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
    def atmosphere(self) -> AtmosphereParams:
        """
        A copy of the atmosphere's constants.
        """
    @property
    def force_ext_W(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        External force, world frame [N], (N, 3) view, held over a step.
        """
    @property
    def ground_effect(self) -> GroundEffectParams:
        """
        A copy of the ground-effect constants.
        """
    @property
    def has_atmosphere(self) -> bool:
        ...
    @property
    def hover_rotor_speed(self) -> float:
        ...
    @property
    def max_rotor_speed(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Upper clamp of the rotor speed command [rad/s], (N, 1) read-only view (set_max_rotor_speed).
        """
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
    def rotor_efficiency(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Per-rotor thrust and drag-torque scale in [0, 1], (N, 4) read-only view (set_rotor_efficiency).
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
    def surfaces_z(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        """
        Floor and ceiling heights [m] the ground effect reads, (N, 2) read-only view (-inf / +inf: none).
        """
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
def atmosphere_grid_wind(params: AtmosphereParams, points: typing.Any) -> typing.Annotated[numpy.typing.NDArray[numpy.float64], "[m, 3]"]:
    """
    The wind grid's trilinear wind at points (N, 3) [m], (N, 3) [m/s].
    """
def dryden_scales(h: typing.Any, wind_20ft: typing.Any) -> dict:
    """
    Dryden (MIL-F-8785C low altitude) intensities sigma_u/v/w [m/s] and scale lengths L_u/v/w [m] at height h [m].
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
def step_batches(batches: collections.abc.Sequence, dt: typing.Any, rotor_speed_cmd: typing.Any, nthreads: typing.Any = 1) -> None:
    """
    Steps several QuadrotorBatch objects in one call (the GIL released): batches[k] by dt[k] (n,) [s] holding its rows of rotor_speed_cmd (sum of the sizes, 4) [rad/s] (the batches' rows one after the other), each exactly as batches[k].step(dt[k], its rows, 1) (bit for bit); nthreads threads over the batches (0 = all cores). Every batch is stepped; the first failure raises ValueError naming batches[k].
    """
def validate_atmosphere(params: AtmosphereParams) -> str:
    """
    Empty string when the atmosphere's constants are usable, else a message naming the field.
    """
def validate_ground_effect(params: GroundEffectParams) -> str:
    """
    Empty string when the ground-effect constants give a finite gain in [1, 10] at every height, else a message.
    """
def validate_params(params: QuadrotorParams) -> str:
    """
    Empty string when the parameters are physical, else a message naming the field.
    """
