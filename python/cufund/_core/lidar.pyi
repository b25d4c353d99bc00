"""
Embree ray casting for LiDAR and depth cameras (paper §2.2).
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['INVALID_ID', 'RaycastScene', 'batch_cast', 'batch_rays', 'mid360_frame', 'scan_frame', 'scan_rays']
class RaycastScene:
    """
    A scene of triangle meshes that casts rays with Embree 3, shaped like Open3D's RaycastingScene.
    
    Add meshes with ``add_triangles``, then ``cast_rays``; the acceleration structure is (re)built on the
    first cast after a change. Casting is multithreaded and releases the GIL.
    """
    INVALID_ID: typing.ClassVar[int] = 4294967295
    @typing.overload
    def __init__(self) -> None:
        ...
    @typing.overload
    def __init__(self, base: RaycastScene) -> None:
        """
        A scene starting with base's geometries as one instance (shared, not copied): a hit on base's geometry g reports id g, meshes added here take the ids after base's. base can no longer change (its add_triangles raises ValueError).
        """
    def add_triangles(self, vertices: typing.Any, triangles: typing.Any) -> int:
        """
        Adds a mesh and returns its geometry id (0, 1, 2, ... in order of addition).
        
        vertices: (V, 3) real [m]; triangles: (T, 3) integer vertex indices, T >= 1. The mesh is copied.
        Degenerate (zero-area) triangles are kept but never hit.
        """
    def cast_rays(self, rays: typing.Any, nthreads: typing.Any = 0, coherent: typing.Any = None) -> dict:
        """
        Casts rays and returns the first hit of each.
        
        rays: (..., 6) rows of (origin xyz, direction xyz), float32 preferred (others are converted); every
        value finite and every direction non-zero, else ValueError naming the ray.
        nthreads: 0 uses every core. coherent: None guesses from the rays (8-wide packets when consecutive
        rays share an origin, regrouped into compact angular tiles on large scenes; otherwise, for 4096 rays
        or more on scenes of 1000 triangles or more, rays sorted by where they head and cast in packets in
        that order), True forces packets of consecutive rays, False single rays in the given order. The
        results are the same either way (bit for bit, except the last bits of distances, barycentrics and
        normals with True).
        
        Returns a dict of arrays shaped like the leading dims of ``rays``:
        ``t_hit`` float32 (inf on a miss; in units of the direction's length), ``geometry_ids`` and
        ``primitive_ids`` uint32 (INVALID_ID on a miss), ``primitive_uvs`` float32 (..., 2) barycentrics,
        ``primitive_normals`` float32 (..., 3) unit geometric normals (zero on a miss), also as ``normals``.
        """
    @property
    def num_geometries(self) -> int:
        ...
    @property
    def num_triangles(self) -> int:
        ...
def batch_cast(scene: RaycastScene, d_S: typing.Any, p_WS: typing.Any, q_WS: typing.Any, *, box_p_W: typing.Any = None, box_q_W: typing.Any = None, box_half_extents: typing.Any = None, box_owner: typing.Any = None, range_min: typing.Any = 0.0, range_max: typing.Any = ..., miss_value: typing.Any = ..., noise_std: typing.Any = 0.0, noise_per_m: typing.Any = 0.0, dropout: typing.Any = 0.0, seed: typing.Any = 0, frame: typing.Any = 0, nthreads: typing.Any = 0) -> numpy.typing.NDArray[numpy.float32]:
    """
    One sensor on each of N vehicles cast in one call (GIL released, threads over vehicles): (N, R) float32.
    
    The rays of batch_rays(d_S, p_WS, q_WS) are cast into ``scene``, each vehicle's in the 8-wide coherent
    packets of ``scene.cast_rays(rays[i], coherent=True)`` (bit for bit its t_hit), and into the vehicles'
    oriented boxes (box_p_W (M, 3) [m], box_q_W (M, 4) [w, x, y, z], box_half_extents (M, 3) [m]; sensor i does
    not see box box_owner[i], -1: none). A value is the distance along the ray's direction in units of its length
    (a range for unit d_S, the depth along the optical axis for pinhole directions (1, -x_n, -y_n)); outside
    [range_min, range_max] or a miss: miss_value. Noise (off by default): a valid return becomes
    max(t + (noise_std + noise_per_m t) z, 0), z standard normal, and is lost (miss_value) with probability
    ``dropout``; vehicle i's draws in frame ``frame`` come from a stream keyed by (seed + i, frame), so vehicle i
    of a batch seeded s draws what a batch of one seeded s + i does.
    """
def batch_rays(d_S: typing.Any, p_WS: typing.Any, q_WS: typing.Any, nthreads: typing.Any = 0) -> numpy.typing.NDArray[numpy.float32]:
    """
    The (N, R, 6) float32 rays batch_cast casts: ray (i, r) leaves p_WS[i] along R(q_WS[i]) d_S[r].
    
    d_S: (R, 3) sensor-frame directions (float32); p_WS (N, 3) [m]; q_WS (N, 4) [w, x, y, z] (normalised here).
    """
def mid360_frame(k: typing.Any, n: typing.Any, point_rate: typing.Any, lasers: typing.Any, spin_rate: typing.Any, sweep_ratio: typing.Any, elevation_min: typing.Any, elevation_max: typing.Any, nthreads: typing.Any = 0) -> tuple[numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.int32], numpy.typing.NDArray[numpy.float64]]:
    """
    Frame k (n rays) of cufund.sensors.patterns.Mid360Pattern: (t [s] from the frame start, azimuth [rad],
    elevation [rad], channel int32, unit directions d_L (n, 3)). Ray i fires at (k n + i) / point_rate, laser
    i % lasers; azimuth 2 pi (spin_rate t + channel / lasers) mod 2 pi, elevation the middle of
    [elevation_min, elevation_max] plus half its width times sin(2 pi spin_rate sweep_ratio t + pi channel / lasers).
    """
def scan_frame(scene: RaycastScene, d_L: typing.Any, t: typing.Any, channel: typing.Any, t0: typing.Any, knot_t: typing.Any, knot_p: typing.Any, knot_q: typing.Any, range_min: typing.Any, range_max: typing.Any, noise: typing.Any = None, keep_draw: typing.Any = None, dropout: typing.Any = 0.0, reflectivity: typing.Any = None, nthreads: typing.Any = 0, *, noise_z: typing.Any = None, range_noise_std: typing.Any = 0.0, range_noise_per_m: typing.Any = 0.0, incidence_noise: typing.Any = 0.0, detect_draw: typing.Any = None, max_range_at_10pct: typing.Any = ..., detection_softness: typing.Any = 0.1, mixed_draw: typing.Any = None, mixed_pixel_probability: typing.Any = 0.0, mixed_pixel_edge_m: typing.Any = 0.3, dt_noise: typing.Any = None, dt_max: typing.Any = ..., intensity_z: typing.Any = None, intensity_noise: typing.Any = 0.0) -> dict:
    """
    One LiDAR frame in one call: the rays of scan_rays (ray i at time t0 + t[i] [s]) cast into ``scene`` (in
    coherent packets, channel by channel: the hits of single rays, up to the last bits of distances, which
    Embree does not promise), and the returns the sensor reports.
    A ray returns when its true range is in [range_min, range_max] [m] and, with ``keep_draw`` (N,), when
    keep_draw[i] >= dropout; its measured range is max(true + noise[i], 0) with ``noise`` (N,) [m] (None: none).
    Intensity: reflectivity[geometry id] x |cos incidence| clipped to [0, 1], float64 (None: |cos incidence|,
    float32). Returns a dict over the returns, in ray order: ``dt`` (M,) t[i], ``points_L`` (M, 3) float32,
    ``ranges`` (M,), ``intensity`` (M,), ``channel`` (M,) int32, ``points_W`` (M, 3) float32 noise-free world
    hits and ``object_ids`` (M,) uint32.
    The realism terms (keyword-only, each off while its draws are None; cufund.sensors.LidarParams documents them):
    ``noise_z`` (N,) unit normals: the range noise is noise_z[i] x sigma, sigma = (range_noise_std +
    range_noise_per_m r) (1 + incidence_noise (1 / cos theta - 1)), theta the incidence angle capped at 85 deg
    (not with ``noise``); ``detect_draw`` (N,) uniforms: a return is lost unless detect_draw[i] < its detection
    probability, 1 up to r_max = max_range_at_10pct sqrt(reflectivity cos theta / 0.1) and 0 past r_max (1 +
    detection_softness), a smoothstep between; ``mixed_draw`` (N, 2) uniforms: a return next to a depth edge of its
    channel (a neighbouring ray's true range more than mixed_pixel_edge_m away) lands at r + mixed_draw[i, 1]
    (r_neighbour - r) when mixed_draw[i, 0] < mixed_pixel_probability; ``dt_noise`` (N,) [s] added to the reported
    dt, clamped to [0, dt_max]; ``intensity_z`` (N,) unit normals: intensity x (1 + s intensity_z[i]), s =
    intensity_noise (1 + (r / r_max)^2) with a finite max_range_at_10pct, else intensity_noise.
    """
def scan_rays(d_L: typing.Any, t: typing.Any, knot_t: typing.Any, knot_p: typing.Any, knot_q: typing.Any) -> numpy.typing.NDArray[numpy.float32]:
    """
    (N, 6) float32 rays of a moving sensor: ray i leaves from the sensor pose at time t[i], interpolated
    between pose knots (knot_t (K,) increasing [s], knot_p (K, 3) p_WL [m], knot_q (K, 4) q_WL [w, x, y, z]
    unit, consecutive signs aligned) linearly in position and by slerp in rotation, along R_WL d_L[i].
    """
INVALID_ID: int = 4294967295
