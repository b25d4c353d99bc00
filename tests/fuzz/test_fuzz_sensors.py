"""Fuzz: sensor parameter records (IMU, GPS, barometer, magnetometer, LiDAR, scan patterns) and one sample each."""

from __future__ import annotations

import dataclasses

from fuzz_support import arrays, expect_good, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

# (builder of a valid record, code that samples the model once into `result`)
RECORDS = {
    "imu": (
        "cufund.sensors.imu.imu_preset('bmi088')",
        "m = cufund.sensors.imu.ImuModel(rec, seed=1)\nresult = np.concatenate(m.measure_static(3))",
    ),
    "gps": (
        "cufund.sensors.gps.GpsParams()",
        "m = cufund.sensors.gps.GpsModel(rec, seed=1)\nfix = m.measure(1.0, np.zeros(3), np.zeros(3))\n"
        "result = np.array([0.0] if fix is None else [fix.latitude_deg, fix.longitude_deg, fix.altitude_m])",
    ),
    "barometer": (
        "cufund.sensors.barometer.BarometerParams()",
        "m = cufund.sensors.barometer.BarometerModel(rec, seed=1)\n"
        "result = np.concatenate([np.ravel(x) for x in m.measure(np.array([10.0]))])",
    ),
    "magnetometer": (
        "cufund.sensors.magnetometer.MagnetometerParams()",
        "m = cufund.sensors.magnetometer.MagnetometerModel(rec, seed=1)\n"
        "result = m.measure(np.array([1.0, 0.0, 0.0, 0.0]))",
    ),
    "lidar": ("cufund.sensors.lidar.LidarParams()", "result = np.zeros(1)"),
    "mid360": ("cufund.sensors.patterns.mid360()", "result = rec.frame(0).directions()"),
    "vlp16": ("cufund.sensors.patterns.vlp16()", "result = rec.frame(0).directions()"),
    "avia": ("cufund.sensors.patterns.avia()", "result = rec.frame(0).directions()"),
}


@st.composite
def record_and_field(draw):
    name = draw(st.sampled_from(sorted(RECORDS)))
    return name, draw(st.integers(0, 40))


@fuzz_settings
@given(
    choice=record_and_field(),
    value=st.one_of(scalars(), arrays([(3,), (4,), (2,)]), st.sampled_from([5e-324, 1e-300, 1e300, 10**9, -1])),
)
def test_sensor_records(server, choice, value):
    name, k = choice
    build, sample = RECORDS[name]
    code = f"""
import dataclasses
base = {build}
fields = [f.name for f in dataclasses.fields(base) if f.init]
field = fields[{k} % len(fields)]
rec = dataclasses.replace(base, **{{field: value}})
{sample}
"""
    outcome, detail = server.run("sensors", "", code, {"value": value}, check="np.isfinite(result).all()", timeout=30)
    expect_good(outcome, detail)


def test_records_exist(server):
    # The table above names real classes: a rename must not make the fuzz silently test nothing.
    for name, (build, sample) in RECORDS.items():
        outcome, detail = server.run("sensors", "", f"rec = {build}\n{sample}", {}, check="np.isfinite(result).all()")
        assert outcome == "ok", (name, detail)


assert dataclasses  # used in the generated code
