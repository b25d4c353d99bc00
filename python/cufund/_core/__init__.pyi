"""
cufund's compiled core. Import the public API from `cufund`, not from here.
"""
from __future__ import annotations
from . import dynamics
from . import esdf
__all__: list[str] = ['dynamics', 'esdf']
__version__: str = '0.1.0'
