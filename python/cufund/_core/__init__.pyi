"""
cufund's compiled core. Import the public API from `cufund`, not from here.
"""
from __future__ import annotations
from . import dynamics
__all__: list[str] = ['dynamics']
__version__: str = '0.1.0'
