"""
Camera images: materials, sun light and shadows (issue 25).
"""
from __future__ import annotations
import cufund._core.lidar
import numpy
import numpy.typing
import typing
__all__: list[str] = ['pattern', 'render_image']
def pattern(texture: typing.SupportsInt | typing.SupportsIndex, a: typing.Any, b: typing.Any, tile: typing.Any, seed: typing.SupportsInt | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
    """
    The procedural pattern (cpp/render/textures.h) at plane coordinates (a, b) [scale units].
    """
def render_image(scene: cufund._core.lidar.RaycastScene, dirs_O: typing.Any, row_p: typing.Any, row_R: typing.Any, width: typing.SupportsInt | typing.SupportsIndex, height: typing.SupportsInt | typing.SupportsIndex, materials: typing.Any, tiles: typing.Any, to_sun: typing.Any, ambient: typing.SupportsFloat | typing.SupportsIndex, shadows: bool, sky: typing.Any, nthreads: typing.Any = 0) -> dict:
    """
    Renders one camera image of a RaycastScene: pixel k looks along ``dirs_O[k]`` (optical frame, (H*W, 3) float32)
    from row r's pose ``row_p[r]`` (p_WO, (H, 3)) and ``row_R[r]`` (R_WO, (H, 3, 3)). ``materials`` (G, 13) float64,
    one row per geometry id: texture code, albedo (3), dark colour (3), scale [m], seed, tile index, offset (2), unused.
    ``tiles`` (T, S, S) float32 noise tiles. Lambert shading: ambient + (1 - ambient) max(0, n.l) with one shadow ray
    per lit pixel when ``shadows`` (else |n.l| without rays). Releases the GIL; packets of 8 coherent rays; the shared
    thread pool. Returns {rgb (H*W, 3) float32 linear, ids (H*W,) int32 (-1: sky), shade (H*W,) float32}.
    """
