"""Worlds of triangle meshes for ray-traced sensors and collisions."""

from . import primitives
from .builtin import BUILTIN, load
from .collision import CollisionChecker, Contact
from .description import world_from_dict, world_from_yaml
from .tunnel_course import TunnelCourse, TunnelCourseParams, TunnelFrame, tunnel_course, tunnel_course_layout
from .world import World, WorldObject

__all__ = ["BUILTIN", "CollisionChecker", "Contact", "World", "WorldObject", "load", "primitives", "TunnelCourse", "TunnelCourseParams", "TunnelFrame", "tunnel_course",
           "tunnel_course_layout", "world_from_dict", "world_from_yaml"]
