"""Registering kinds from Python in a fresh interpreter: the built-ins are loaded first, so a plug-in's kind may
name a built-in sensor type and replace a built-in kind (the registry loads them on the first register, not only
on the first lookup)."""

from __future__ import annotations

import subprocess
import sys

CODE = """
import dataclasses
import cufund
from cufund.core.registry import Kind, available, lookup, register
from cufund.sensors.imu import ImuParams
mine = register(Kind("sensor", "my_imu", ImuParams, lambda p, ctx: [], None, "mine", sensor_type="imu"))
pid = available("controller")["pid"]
register(dataclasses.replace(pid, doc="my pid"), replace=True)
assert lookup("controller", "pid").doc == "my pid", lookup("controller", "pid").doc
assert lookup("sensor", "my_imu") is mine
try:
    register(dataclasses.replace(pid, doc="again"))
except ValueError as e:
    assert "registered already" in str(e)
else:
    raise AssertionError("a second pid without replace=True was accepted")
print("ok")
"""


def test_register_before_any_lookup_sees_the_built_ins():
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]
