"""The land detector: a follower-flown landing whose reference ends above the ground (an estimate reading the vehicle
low) descends on, disarms within 1 s of touchdown (ground truth) and ends the run; it never fires in flight."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from cufund.core.messages import Topics
from cufund.missions.land_detector import LandDetector, LandDetectorComponent, land_detector_done
from cufund.scenarios import load_scenario
from cufund.scenarios.build import build_simulation, done_condition, measure_run


class _Raised:
    """The follower's reference ``dz`` higher: what the vehicle flies when its estimate reads it ``dz`` low."""

    def __init__(self, ref: Any, dz: float) -> None:
        self.ref, self.dz = ref, dz
        self.t_start, self.t_end, self.duration = ref.t_start, ref.t_end, ref.duration

    def sample(self, t: Any) -> Any:
        s = self.ref.sample(t)
        p = np.array(s.p_W, float)
        p[..., 2] += self.dz
        return dataclasses.replace(s, p_W=p)


def _run(dz: float, descend: bool = True, detector_only: bool = False):
    built = build_simulation(load_scenario("square", ["failsafe=off"]))
    det = next(c for c in built.simulator.components if isinstance(c, LandDetectorComponent))
    follower = det.follower
    follower.initial_trajectory = follower.trajectory = _Raised(follower.initial_trajectory, dz)
    det.ground_tol = dz + 0.1  # its end is dz above its start (with a drifted estimate both read the pad's height)
    if not descend:
        det.grace_s = np.inf
    # detector_only: the run ends on the detector's disarm alone (not on the harness's truth check of a rest)
    done = land_detector_done(built.simulator.components, None) if detector_only else done_condition(built)
    result = built.simulator.run(25.0, done=done)
    return det, result, measure_run(built, result)


def test_landing_above_the_ground_descends_on_disarms_after_touchdown_and_ends():
    det, result, run = _run(0.3, detector_only=True)
    assert run.metrics["status"] == "completed" and result.message == "done condition met"
    assert det.disarmed_at is not None
    st = result.states
    t, z, vz = np.asarray(st["t"]), np.asarray(st["p_W"])[:, 2], np.asarray(st["v_W"])[:, 2]
    down = np.flatnonzero((t > det.follower.initial_trajectory.t_end) & (z < 0.02) & (np.abs(vz) < 0.05))
    assert len(down), "the vehicle never reached the ground"
    touchdown = float(t[down[0]])
    assert touchdown <= det.disarmed_at <= touchdown + 1.0
    assert z[-1] < 0.02


def test_landing_above_the_ground_ends_the_run():
    assert _run(0.3)[2].metrics["status"] == "completed"
    assert _run(0.3, descend=False)[2].metrics["status"] == "timeout"  # the regression: it hovered to the end


def test_hovering_above_the_ground_does_not_disarm():
    det, result, run = _run(0.05, descend=False)  # held 5 cm up, no descent: not landed
    assert det.disarmed_at is None and run.metrics["status"] == "timeout"
    assert np.asarray(result.states["p_W"])[-1, 2] > 0.03


def test_never_fires_in_a_nominal_square_flight():
    built = build_simulation(load_scenario("square", ["failsafe=off"]))
    det = next(c for c in built.simulator.components if isinstance(c, LandDetectorComponent))
    result = built.simulator.run(40.0, done=done_condition(built))
    assert det.disarmed_at is None and result.message == "done condition met"
    # the touchdown test run over the whole recorded flight (not only after the reference's end)
    sp = result.topics[str(Topics.ATTITUDE_SETPOINT)]
    st = result.states
    d = LandDetector(built.context.vehicle.mass * 9.81)
    t_st, vz = np.asarray(st["t"]), np.asarray(st["v_W"])[:, 2]
    z = np.asarray(st["p_W"])[:, 2]
    fired = [
        float(t)
        for t, thrust in zip(sp["t"], sp["thrust"], strict=True)
        if d.update(float(t), float(vz[min(np.searchsorted(t_st, t), len(vz) - 1)]), float(thrust))
    ]
    airborne = t_st[z > 0.05]
    assert not fired or fired[0] > airborne[-1], f"fired at {fired[0]:.2f} s in flight"


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="hover_thrust_N"):
        LandDetector(0.0)
    with pytest.raises(ValueError, match="low_thrust_fraction"):
        LandDetector(10.0, low_thrust_fraction=1.5)


def test_square_lio_landing_on_a_drifted_estimate_ends():
    """The LiDAR lost from 11 s with failsafe off: the IMU-propagated estimate reads the vehicle ~3 cm low at the
    reference's end, so it hovered there until the duration (timeout at 40 s) before the land detector's descent."""
    sets = ["failsafe=off", "faults.lidar_dropout.t_start=11", "faults.lidar_dropout.duration=1000"]
    built = build_simulation(load_scenario("square_lio", sets))
    det = next(c for c in built.simulator.components if isinstance(c, LandDetectorComponent))
    result = built.simulator.run(40.0, done=done_condition(built))
    assert det.descending and result.message == "done condition met" and result.states["t"][-1] < 20.0
    assert result.states["p_W"][-1, 2] < 0.02
