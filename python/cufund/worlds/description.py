"""Worlds from a YAML description (or the same structure as plain dicts).

    name: my_world
    objects:
      - {type: plane, size: [10, 10], position: [0, 0, 0], label: floor}
      - {type: box, size: [1, 1, 2], position: [3, 0, 1], yaw: 0.3, label: crate, color: [0.6, 0.4, 0.2]}
      - {type: cylinder, radius: 0.2, height: 3, position: [0, 4, 1.5], label: tree}
      - {type: sphere, radius: 0.5, position: [2, 2, 1]}
      - {type: tunnel_frame, position: [0, 0, 1], width: 0.5, height: 1.0}
      - {type: mesh, path: chair.obj, position: [1, 1, 0], scale: 0.01}
      - {type: box, size: [2, 0.1, 1], position: [0, 3, 1], material: {texture: brick, scale: 0.25}}

Each entry's keys are the keyword arguments of the matching ``World.add_*`` method (``mesh``:
``World.load_mesh``; a relative ``path``, or a material's ``image``, is taken from the YAML file's folder;
``material`` is a :class:`cufund.worlds.materials.Material`'s fields, seen only by cameras). Unknown types or keys
raise ``ConfigError`` naming them.
"""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

from cufund.core.config import ConfigError, load_yaml

from .materials import Material
from .world import World

_ADDERS = {
    "box": "add_box",
    "plane": "add_plane",
    "cylinder": "add_cylinder",
    "sphere": "add_sphere",
    "tunnel_frame": "add_tunnel_frame",
    "mesh": "load_mesh",
}


def world_from_dict(data: Any, base_dir: str | Path = ".") -> World:
    """Builds a ``World`` from ``{"name": ..., "objects": [...]}``."""
    if not isinstance(data, dict):
        raise ConfigError(f"a world description must be a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - {"name", "objects"})
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in world description; expected one of: name, objects")
    world = World(str(data.get("name", "world")))
    objects = data.get("objects", [])
    if not isinstance(objects, list):
        raise ConfigError(f"objects must be a list, got {type(objects).__name__}")
    for i, entry in enumerate(objects):
        where = f"objects[{i}]"
        if not isinstance(entry, dict) or "type" not in entry:
            raise ConfigError(f"{where} must be a mapping with a 'type' key ({', '.join(_ADDERS)})")
        kind = entry["type"]
        if kind not in _ADDERS:
            raise ConfigError(f"{where}.type must be one of {', '.join(_ADDERS)}, got {kind!r}")
        method = getattr(world, _ADDERS[kind])
        allowed = list(inspect.signature(method).parameters)
        kwargs = {k: v for k, v in entry.items() if k != "type"}
        bad = sorted(set(kwargs) - set(allowed))
        if bad:
            raise ConfigError(f"unknown key {bad[0]!r} in {where} ({kind}); expected one of: {', '.join(allowed)}")
        if kind == "mesh" and "path" in kwargs:
            if not isinstance(kwargs["path"], str):
                raise ConfigError(f"{where}.path must be a file name (string), got {kwargs['path']!r}")
            path = Path(kwargs["path"])
            kwargs["path"] = path if path.is_absolute() else Path(base_dir) / path
        try:
            if kwargs.get("material") is not None:  # a relative image from the YAML's folder
                kwargs["material"] = Material.of(kwargs["material"], base_dir)
            method(**kwargs)
        except TypeError as e:  # a missing required key
            raise ConfigError(f"{where} ({kind}): {e}") from e
        except ValueError as e:
            raise ConfigError(f"{where} ({kind}): {e}") from e
    return world


def world_from_yaml(path: str | Path) -> World:
    """Loads a world description from a YAML file."""
    path = Path(path)
    return world_from_dict(load_yaml(path), base_dir=path.parent)
