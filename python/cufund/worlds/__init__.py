"""Worlds of triangle meshes for ray-traced sensors and collisions."""

from . import primitives
from .builtin import BUILTIN, load
from .collision import CollisionChecker, Contact
from .description import world_from_dict, world_from_yaml
from .world import World, WorldObject

__all__ = [
    "BUILTIN",
    "CollisionChecker",
    "Contact",
    "World",
    "WorldObject",
    "load",
    "primitives",
    "world_from_dict",
    "world_from_yaml",
]
