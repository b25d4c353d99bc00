"""A world of triangle meshes, each with an id, a semantic label and a colour."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from cufund import _core

from . import primitives
from .materials import Material


@dataclasses.dataclass(frozen=True)
class WorldObject:
    """One rigid mesh of the world, in world coordinates (ENU, z up)."""

    id: int
    """Index in ``World.objects``; equals the ray caster's geometry id."""
    label: str
    """Semantic label, e.g. "wall", "tunnel_frame", "tree"."""
    color: tuple[float, float, float]
    """Albedo as RGB in [0, 1]."""
    vertices: np.ndarray
    """(V, 3) float64 vertex positions in the world frame [m]."""
    triangles: np.ndarray
    """(T, 3) int64 vertex indices."""
    reflectivity: float = 0.8
    """LiDAR reflectivity in [0, 1]; intensity = reflectivity × |cos(incidence)|."""
    material: Material | None = None
    """How cameras see it (:class:`cufund.worlds.materials.Material`); None: plain ``color``."""
    uvs: np.ndarray | None = None
    """(V, 2) texture coordinates per vertex (OBJ ``vt``) for an image material, or None."""


def _floats(name: str, value: object, what: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {what}, got {value!r}") from None


def _pose_matrix(position: object, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    p = _floats("position", position, "3 finite numbers [m]")
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"position must be 3 finite numbers [m], got {position!r}")
    if isinstance(yaw, bool) or not isinstance(yaw, (int, float, np.integer, np.floating)):
        raise ValueError(f"yaw must be a finite number [rad], got {yaw!r}")
    yaw = float(yaw)
    if not np.isfinite(yaw):
        raise ValueError(f"yaw must be finite [rad], got {yaw}")
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), p


def _color(color: object) -> tuple[float, float, float]:
    c = _floats("color", color, "3 numbers in [0, 1] (RGB)")
    if c.shape != (3,) or not np.all((c >= 0.0) & (c <= 1.0)):
        raise ValueError(f"color must be 3 numbers in [0, 1] (RGB), got {color!r}")
    return (float(c[0]), float(c[1]), float(c[2]))


class World:
    """Triangle meshes for ray-traced sensors and collisions.

    Add objects with ``add_mesh`` or the primitive helpers; each returns its ``WorldObject``. The
    Embree scene (``raycast_scene``) is built on first use and rebuilt after changes.
    """

    def __init__(self, name: str = "world") -> None:
        self.name = name
        self._objects: list[WorldObject] = []
        self._scene: _core.lidar.RaycastScene | None = None

    @property
    def objects(self) -> tuple[WorldObject, ...]:
        return tuple(self._objects)

    def __len__(self) -> int:
        return len(self._objects)

    def add_mesh(
        self,
        vertices: object,
        triangles: object,
        label: str = "object",
        color: object = (0.7, 0.7, 0.7),
        position: object = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        reflectivity: float = 0.8,
        material: object = None,
        uvs: object = None,
    ) -> WorldObject:
        """Adds a mesh given in its own frame, placed at ``position`` [m] rotated by ``yaw`` [rad] about z.
        ``material``: a :class:`~cufund.worlds.materials.Material` (or a mapping of its fields) for cameras;
        ``uvs``: (V, 2) texture coordinates of an image material."""
        v = _floats("vertices", vertices, "an array of shape (V, 3) [m]")
        f = np.asarray(triangles)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices must have shape (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] == 0:
            raise ValueError(f"triangles must have shape (T, 3) with T >= 1, got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"triangles must have an integer dtype, got {f.dtype}")
        if not np.all(np.isfinite(v)):
            raise ValueError("vertices must be finite")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"triangles must index vertices in [0, {len(v)}), got [{f.min()}, {f.max()}]")
        if (
            isinstance(reflectivity, bool)
            or not isinstance(reflectivity, (int, float, np.integer, np.floating))
            or not 0.0 <= float(reflectivity) <= 1.0
        ):
            raise ValueError(f"reflectivity must be in [0, 1], got {reflectivity}")
        R, p = _pose_matrix(position, yaw)
        mat = None if material is None else Material.of(material)
        uv = None
        if uvs is not None:
            uv = _floats("uvs", uvs, "an array of shape (V, 2)")
            if uv.shape != (len(v), 2) or not np.all(np.isfinite(uv)):
                raise ValueError(f"uvs must be {len(v)} finite (u, v) pairs, one per vertex, got shape {uv.shape}")
        obj = WorldObject(
            len(self._objects),
            str(label),
            _color(color),
            v @ R.T + p,
            f.astype(np.int64),
            float(reflectivity),
            mat,
            uv,
        )
        self._objects.append(obj)
        self._scene = None
        return obj

    def add_box(
        self,
        size: Any,
        position: object,
        yaw: float = 0.0,
        label: str = "box",
        color: object = (0.7, 0.7, 0.7),
        material: object = None,
    ) -> WorldObject:
        """Box of edge lengths ``size`` (sx, sy, sz) [m] centred at ``position``."""
        return self.add_mesh(*primitives.box(size), label, color, position, yaw, material=material)

    def add_plane(
        self,
        size: Any,
        position: object,
        yaw: float = 0.0,
        label: str = "floor",
        color: object = (0.5, 0.5, 0.5),
        material: object = None,
    ) -> WorldObject:
        """Horizontal rectangle (sx, sy) [m] at ``position``, facing up."""
        return self.add_mesh(*primitives.plane(size), label, color, position, yaw, material=material)

    def add_cylinder(
        self,
        radius: float,
        height: float,
        position: object,
        label: str = "cylinder",
        color: object = (0.7, 0.7, 0.7),
        segments: int = 32,
        material: object = None,
    ) -> WorldObject:
        """Vertical capped cylinder centred at ``position``."""
        return self.add_mesh(*primitives.cylinder(radius, height, segments), label, color, position, material=material)

    def add_sphere(
        self,
        radius: float,
        position: object,
        label: str = "sphere",
        color: object = (0.7, 0.7, 0.7),
        subdivisions: int = 3,
        material: object = None,
    ) -> WorldObject:
        return self.add_mesh(*primitives.sphere(radius, subdivisions), label, color, position, material=material)

    def add_tunnel_frame(
        self,
        position: object,
        width: float = 0.5,
        height: float = 1.0,
        depth: float = 0.05,
        thickness: float = 0.05,
        yaw: float = 0.0,
        label: str = "tunnel_frame",
        color: object = (0.9, 0.4, 0.1),
        material: object = None,
    ) -> WorldObject:
        """Rectangular frame around an opening width (y) × height (z) [m] centred at ``position``;
        flown through along x (rotated by ``yaw``)."""
        mesh = primitives.tunnel_frame(width, height, depth, thickness)
        return self.add_mesh(*mesh, label, color, position, yaw, material=material)

    def load_mesh(
        self,
        path: str | Path,
        label: str | None = None,
        color: object = (0.7, 0.7, 0.7),
        position: object = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        scale: float = 1.0,
        material: object = None,
    ) -> WorldObject:
        """Adds a mesh from an OBJ, STL or PLY file (read with trimesh), scaled by ``scale``. An OBJ with UVs
        (``vt``) and an MTL whose ``map_Kd`` names a PNG gets that image as its material unless ``material`` is
        given."""
        import trimesh  # imported here: only mesh files need it

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"mesh file {str(path)!r} does not exist")
        if (
            isinstance(scale, bool)
            or not isinstance(scale, (int, float, np.integer, np.floating))
            or not 0 < scale < float("inf")
        ):
            raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
        if path.suffix.lower() == ".obj":
            _check_obj_faces(path)
        # an OBJ's MTL and texture are read by _mesh_texture alone (in the mesh's folder, regular files only):
        # trimesh's own read opened whatever mtllib named (a FIFO blocked it for ever) and decoded the image again
        only_geometry: dict[str, Any] = {"skip_materials": True} if path.suffix.lower() == ".obj" else {}
        try:
            mesh: Any = trimesh.load(path, force="mesh", process=False, **only_geometry)
            faces, vertices = np.asarray(mesh.faces), np.asarray(mesh.vertices, dtype=float)
        except Exception as e:  # trimesh raises IndexError, KeyError, NotImplementedError, ... on bad files
            raise ValueError(
                f"mesh file {str(path)!r} must be a readable OBJ, STL or PLY mesh: {type(e).__name__}: {e}"
            ) from None
        if faces.ndim != 2 or len(faces) == 0:
            raise ValueError(f"mesh file {str(path)!r} holds no triangles")
        from cufund.core.limits import current

        cap = current().mesh_max_triangles
        if len(faces) > cap:
            raise ValueError(
                f"mesh file {str(path)!r} holds {len(faces)} triangles, more than mesh_max_triangles = "
                f"{cap} (cufund.core.limits.configure(mesh_max_triangles=...))"
            )
        uvs, mtl_material = _mesh_texture(mesh, path)
        mat = mtl_material if material is None else material
        return self.add_mesh(vertices * scale, faces, label or path.stem, color, position, yaw, material=mat, uvs=uvs)

    # --- queries ------------------------------------------------------------------------------
    @property
    def raycast_scene(self) -> _core.lidar.RaycastScene:
        """The Embree scene of all objects; geometry id == object id."""
        if self._scene is None:
            scene = _core.lidar.RaycastScene()
            for obj in self._objects:
                gid = scene.add_triangles(obj.vertices.astype(np.float32), obj.triangles)
                assert gid == obj.id
            self._scene = scene
        return self._scene

    def colors(self) -> np.ndarray:
        """(n_objects + 1, 3) albedo per object id; the last row (index -1) is black for misses."""
        return np.array([o.color for o in self._objects] + [(0.0, 0.0, 0.0)], dtype=float).reshape(-1, 3)

    def materials(self) -> list[Material | None]:
        """Each object's material (None: plain colour), by object id."""
        return [o.material for o in self._objects]

    def reflectivities(self) -> np.ndarray:
        """(n_objects + 1,) reflectivity per object id; the last entry (misses) is 0."""
        return np.array([o.reflectivity for o in self._objects] + [0.0], dtype=float)

    def labels(self) -> list[str]:
        return [o.label for o in self._objects]

    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned [min, max] corners of all objects [m]."""
        if not self._objects:
            raise ValueError("the world is empty: no bounds")
        v = np.vstack([o.vertices for o in self._objects])
        return np.stack([v.min(0), v.max(0)])

    def __repr__(self) -> str:
        tris = sum(len(o.triangles) for o in self._objects)
        return f"World({self.name!r}, {len(self._objects)} objects, {tris} triangles)"


def _check_obj_faces(path: Path) -> None:
    """OBJ vertex indices are 1-based (negative: relative to the last vertex); trimesh silently turns an index
    0 or one past the vertices into a wrong triangle, so those are errors naming the file and line."""
    vertices = 0
    with path.open("r", encoding="utf-8", errors="replace") as f:
        for line_no, line in enumerate(f, 1):
            head = line[:2]
            if head == "v " or head == "v\t":
                vertices += 1
            elif head == "f " or head == "f\t":
                for token in line.split()[1:]:
                    field = token.split("/")[0]
                    try:
                        k = int(field)
                    except ValueError:
                        raise ValueError(f"{path}:{line_no}: face index {token!r} is not an integer") from None
                    if k == 0 or k > vertices or -k > vertices:
                        raise ValueError(
                            f"{path}:{line_no}: face index {k} must be in [1, {vertices}] (OBJ indices "
                            f"start at 1; negative ones count back from the last vertex)"
                        )


def _mesh_texture(mesh: Any, path: Path) -> tuple[np.ndarray | None, Material | None]:
    """The UVs of a trimesh mesh and, when its MTL names a readable image (map_Kd), that image as a Material;
    (None, None) without UVs. A broken texture reference is an error naming the mesh file."""
    visual = getattr(mesh, "visual", None)
    uv = getattr(visual, "uv", None)
    if uv is None:
        return None, None
    uv = np.asarray(uv, dtype=float)
    if uv.ndim != 2 or uv.shape != (len(mesh.vertices), 2) or not np.all(np.isfinite(uv)):
        raise ValueError(f"mesh file {str(path)!r}: texture coordinates must be one finite (u, v) per vertex")
    folder = path.parent.resolve()

    def inside(name: str, what: str) -> Path:
        # as trimesh's resolver: a file the mesh names lies in the mesh's folder (an absolute path or ../ that
        # leaves it is refused, not read)
        p = (folder / name).resolve()
        if not p.is_relative_to(folder):
            raise ValueError(f"mesh file {str(path)!r}: {what} {name!r} lies outside the mesh's folder")
        return p

    mtl = path.with_suffix(".mtl")
    if path.suffix.lower() == ".obj":  # the MTL the OBJ names (mtllib), else the OBJ's name with .mtl
        with path.open("r", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("mtllib ") and line.split(maxsplit=1)[1].strip():
                    mtl = inside(line.split(maxsplit=1)[1].strip(), "mtllib")
                    break
    image = None
    if mtl.is_file():
        with mtl.open("r", encoding="utf-8", errors="replace") as f:
            for line in f:
                parts = line.split()
                if len(parts) >= 2 and parts[0] == "map_Kd":
                    image = inside(parts[-1], "its MTL's map_Kd")
                    break
    if image is None:
        return uv, None
    try:
        return uv, Material(texture="image", image=str(image), albedo=(1.0, 1.0, 1.0))
    except ValueError as e:
        raise ValueError(f"mesh file {str(path)!r}: its MTL's map_Kd: {e}") from None
