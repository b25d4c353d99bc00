"""
Learning environments on the quadrotor batch (issue 28).
"""
from __future__ import annotations
import collections.abc
import cufund._core.dynamics
import numpy
import numpy.typing
import typing
__all__: list[str] = ['EnvBatch', 'EnvTaskParams', 'PrismScene', 'prism_depth_cast', 'velocity_command']
class PrismScene:
    """
    Vertical convex prisms and horizontal rectangles for prism_depth_cast (cpp/envs/prism_cast.h).
    """
    def __init__(self, planes: typing.Any, plane_begin: typing.Any, prisms: typing.Any, rects: typing.Any) -> None:
        """
        planes (K, 3) (nx, ny, c): inside nx x + ny y <= c; prism j's planes plane_begin[j]:plane_begin[j + 1]; prisms (P, 6) (zmin, zmax, x0, x1, y0, y1: its z extent and xy bounding box) [m]; rects (M, 5) (z, x0, x1, y0, y1) [m].
        """
    @property
    def num_prisms(self) -> int:
        ...
    @property
    def num_rects(self) -> int:
        ...
class EnvTaskParams:
    """
    A task as cpp/envs reads it (built by cufund.envs from TaskConfig).
    """
    imu_noise: bool
    def __init__(self) -> None:
        ...
    def set_rate_gains(self, k_p: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[3, 1]"], k_i: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[3, 1]"], k_d: typing.Annotated[numpy.typing.ArrayLike, numpy.float64, "[3, 1]"], feed_forward: typing.SupportsFloat | typing.SupportsIndex, integrator_limit: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def action_mode(self) -> int:
        ...
    @action_mode.setter
    def action_mode(self, arg1: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def alive(self) -> float:
        ...
    @alive.setter
    def alive(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def attitude_gain(self) -> float:
        ...
    @attitude_gain.setter
    def attitude_gain(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def bound(self) -> float:
        ...
    @bound.setter
    def bound(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def crash(self) -> float:
        ...
    @crash.setter
    def crash(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def crash_z(self) -> float:
        ...
    @crash_z.setter
    def crash_z(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def drag(self) -> list[float]:
        ...
    @drag.setter
    def drag(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def dt(self) -> float:
        ...
    @dt.setter
    def dt(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gate_size(self) -> float:
        ...
    @gate_size.setter
    def gate_size(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gyro_turn_on(self) -> float:
        ...
    @gyro_turn_on.setter
    def gyro_turn_on(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gyro_walk(self) -> float:
        ...
    @gyro_walk.setter
    def gyro_walk(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def gyro_white(self) -> float:
        ...
    @gyro_white.setter
    def gyro_white(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def hold_s(self) -> list[float]:
        ...
    @hold_s.setter
    def hold_s(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def inertia(self) -> list[float]:
        ...
    @inertia.setter
    def inertia(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def latency_steps(self) -> list[float]:
        ...
    @latency_steps.setter
    def latency_steps(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def lookahead(self) -> float:
        ...
    @lookahead.setter
    def lookahead(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def mass(self) -> list[float]:
        ...
    @mass.setter
    def mass(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def max_rate(self) -> float:
        ...
    @max_rate.setter
    def max_rate(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def max_speed(self) -> float:
        ...
    @max_speed.setter
    def max_speed(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def max_steps(self) -> int:
        ...
    @max_steps.setter
    def max_steps(self, arg0: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def motor_constant(self) -> list[float]:
        ...
    @motor_constant.setter
    def motor_constant(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def motor_lag(self) -> list[float]:
        ...
    @motor_lag.setter
    def motor_lag(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def n_ahead(self) -> int:
        ...
    @n_ahead.setter
    def n_ahead(self, arg0: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def obs_size(self) -> int:
        ...
    @property
    def position_noise(self) -> list[float]:
        ...
    @position_noise.setter
    def position_noise(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def progress(self) -> float:
        ...
    @progress.setter
    def progress(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rate_d_cutoff_hz(self) -> float:
        ...
    @rate_d_cutoff_hz.setter
    def rate_d_cutoff_hz(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def rate_i_scale(self) -> float:
        ...
    @rate_i_scale.setter
    def rate_i_scale(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def reach_radius(self) -> float:
        ...
    @reach_radius.setter
    def reach_radius(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def reached(self) -> float:
        ...
    @reached.setter
    def reached(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def segment_s(self) -> list[float]:
        ...
    @segment_s.setter
    def segment_s(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def spawn_center(self) -> list[float]:
        ...
    @spawn_center.setter
    def spawn_center(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def spawn_extent(self) -> list[float]:
        ...
    @spawn_extent.setter
    def spawn_extent(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def spawn_rate(self) -> float:
        ...
    @spawn_rate.setter
    def spawn_rate(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def spawn_speed(self) -> float:
        ...
    @spawn_speed.setter
    def spawn_speed(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def spawn_tilt(self) -> float:
        ...
    @spawn_tilt.setter
    def spawn_tilt(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def substeps(self) -> int:
        ...
    @substeps.setter
    def substeps(self, arg0: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def targets(self) -> list[float]:
        ...
    @targets.setter
    def targets(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def task(self) -> int:
        ...
    @task.setter
    def task(self, arg1: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    @property
    def velocity_gain(self) -> float:
        ...
    @velocity_gain.setter
    def velocity_gain(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def velocity_noise(self) -> list[float]:
        ...
    @velocity_noise.setter
    def velocity_noise(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def w_action(self) -> float:
        ...
    @w_action.setter
    def w_action(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def w_position(self) -> float:
        ...
    @w_position.setter
    def w_position(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def w_rate(self) -> float:
        ...
    @w_rate.setter
    def w_rate(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def w_smooth(self) -> float:
        ...
    @w_smooth.setter
    def w_smooth(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def w_velocity(self) -> float:
        ...
    @w_velocity.setter
    def w_velocity(self, arg0: typing.SupportsFloat | typing.SupportsIndex) -> None:
        ...
    @property
    def waypoint_jitter(self) -> list[float]:
        ...
    @waypoint_jitter.setter
    def waypoint_jitter(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
    @property
    def wind(self) -> list[float]:
        ...
    @wind.setter
    def wind(self, arg0: collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex]) -> None:
        ...
class EnvBatch:
    """
    N envs of one task over a QuadrotorBatch (cpp/envs/env_batch.h).
    """
    def __init__(self, params: cufund._core.dynamics.QuadrotorParams, task: EnvTaskParams, num_envs: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    def end_episodes(self, mask: typing.Any) -> None:
        """
        Ends the episodes of the envs where mask (N,) is True: the next step resets them.
        """
    def reference(self, env: typing.SupportsInt | typing.SupportsIndex, t: typing.SupportsFloat | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
        """
        Reference mode: env's reference p_W, v_W, a_W (9,) at time t [s] of its episode.
        """
    def reset(self, seed: typing.SupportsInt | typing.SupportsIndex | None = None) -> numpy.typing.NDArray[numpy.float32]:
        """
        Resets every env (seeding env i's stream with seed + i when given); obs.
        """
    def step(self, actions: typing.Any, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> tuple[numpy.typing.NDArray[numpy.float32], numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.bool], numpy.typing.NDArray[numpy.bool]]:
        """
        One step of every env: (obs, reward, terminated, truncated); next-step autoreset.
        """
    def waypoints(self, env: typing.SupportsInt | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
        """
        Reference mode: env's waypoints (K, 3) as jittered at its last reset.
        """
    @property
    def batch(self) -> cufund._core.dynamics.QuadrotorBatch:
        """
        The QuadrotorBatch the envs fly (its state arrays are views).
        """
    @property
    def drawn_scales(self) -> numpy.typing.NDArray[numpy.float64]:
        ...
    @property
    def episode_steps(self) -> numpy.typing.NDArray[numpy.int32]:
        ...
    @property
    def latency(self) -> numpy.typing.NDArray[numpy.int32]:
        ...
    @property
    def obs_size(self) -> int:
        ...
    @property
    def size(self) -> int:
        ...
    @property
    def target_index(self) -> numpy.typing.NDArray[numpy.int32]:
        ...
def prism_depth_cast(scene: PrismScene, d_S: typing.Any, p_WS: typing.Any, q_WS: typing.Any, *, width: typing.SupportsInt | typing.SupportsIndex, height: typing.SupportsInt | typing.SupportsIndex, focal: typing.SupportsFloat | typing.SupportsIndex, range_min: typing.Any = 0.0, range_max: typing.Any = ..., miss_value: typing.Any = ..., noise_std: typing.Any = 0.0, noise_per_m: typing.Any = 0.0, dropout: typing.Any = 0.0, seed: typing.Any = 0, frame: typing.Any = 0, nthreads: typing.Any = 0) -> numpy.typing.NDArray[numpy.float32]:
    """
    (N, width * height) float32 depths of N pinhole cameras (d_S the camera's rays, DepthCameraSpec.directions()) in a PrismScene, GIL released: what cufund._core.lidar.batch_cast returns for the scene's meshes (no boxes), within float rounding, with the same range model and noise streams.
    """
def velocity_command(a: typing.Annotated[collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex], "FixedSize(4)"], v_W: typing.Annotated[collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex], "FixedSize(3)"], q_WB: typing.Annotated[collections.abc.Sequence[typing.SupportsFloat | typing.SupportsIndex], "FixedSize(4)"], mass: typing.SupportsFloat | typing.SupportsIndex, gravity: typing.SupportsFloat | typing.SupportsIndex, max_thrust: typing.SupportsFloat | typing.SupportsIndex, max_speed: typing.SupportsFloat | typing.SupportsIndex, max_rate: typing.SupportsFloat | typing.SupportsIndex, velocity_gain: typing.SupportsFloat | typing.SupportsIndex, attitude_gain: typing.SupportsFloat | typing.SupportsIndex) -> tuple[float, typing.Annotated[numpy.typing.NDArray[numpy.float64], "[3, 1]"]]:
    """
    The velocity action mode's (collective thrust [N], body-rate setpoint [rad/s] (3,)) for action a (4,): the envs' formula, shared by the policy controller.
    """
