"""
cufund's compiled core. Import the public API from `cufund`, not from here.
"""
from __future__ import annotations
from . import dynamics
from . import control
from . import lidar
from . import perception
from . import esdf
from . import odometry
from . import planning
from . import logs
from . import envs
from . import render
__all__: list[str] = ['control', 'dynamics', 'envs', 'esdf', 'lidar', 'logs', 'odometry', 'perception', 'planning', 'render', 'thread_pool_size']
def thread_pool_size() -> int:
    """
    Threads of the shared C++ pool, the caller included (CUFUND_NUM_THREADS, else the CPUs this process may use).
    """
__version__: str = '0.1.0'
