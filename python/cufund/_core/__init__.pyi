"""
cufund's compiled core. Import the public API from `cufund`, not from here.
"""
from __future__ import annotations
from . import dynamics
from . import control
from . import lidar
from . import esdf
from . import odometry
__all__: list[str] = ['control', 'dynamics', 'esdf', 'lidar', 'odometry']
__version__: str = '0.1.0'
