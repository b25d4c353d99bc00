"""The simulator's own cost per physics node, and the flight-control stack's CPU per call (not a test).

1. Overhead per 1 kHz physics node: the CPU of ``Simulator.run`` minus the CPU of the same physics steps alone,
   with trivial components (``step`` does nothing, or reads the truth for the sensor-like ones), so what remains
   is scheduling, ground-truth snapshots, the state record and the divergence checks. Four component sets: none;
   a 500 Hz rate loop; the square's 500 + 3 x 250 Hz with a ``done`` condition; the same plus an estimator's
   200 Hz and two truth readers (IMU 200 Hz, pose 10 Hz).
2. ``square_mocap`` (PID cascade on an estimate, rate loop on the gyro): process CPU per simulated second and
   each component's wall time per call.

CPU times (``time.thread_time`` / ``process_time``), best of several runs, so the figures hold on a loaded
machine; the load is printed. Run: ``.venv/bin/python benchmarks/bench_simulator.py``
"""

from __future__ import annotations

import os
import time

import cufund
from cufund import Simulator, Topics

PARAMS = cufund.vehicle.presets.cu_astro()
DURATION = 15.0
REPEATS = 7


class Software(cufund.Component):
    """Flight software that does nothing (no truth access)."""

    def __init__(self, rate_hz: float, name: str) -> None:
        self.rate_hz, self.name = rate_hz, name

    def step(self, t: float, bus) -> None:  # type: ignore[no-untyped-def]
        pass


class TruthReader(cufund.Component):
    """A sensor-like component: reads the ground truth."""

    inputs = (Topics.TRUTH_ODOMETRY,)
    reads_truth = True

    def __init__(self, rate_hz: float, name: str) -> None:
        self.rate_hz, self.name = rate_hz, name

    def step(self, t: float, bus) -> None:  # type: ignore[no-untyped-def]
        bus.latest(Topics.TRUTH_ODOMETRY)


def physics_alone() -> float:
    quad = cufund.Quadrotor(PARAMS)
    quad.hover([0.0, 0.0, 50.0])
    cmd = quad.state.rotor_speeds.copy()
    c0 = time.thread_time()
    for _ in range(int(DURATION * 1000)):
        quad.step(0.001, cmd)
    return time.thread_time() - c0


def simulated(spec: list, done: bool) -> float:
    quad = cufund.Quadrotor(PARAMS)
    quad.hover([0.0, 0.0, 50.0])
    sim = Simulator(quad)
    for i, (kind, rate) in enumerate(spec):
        sim.add(kind(rate, f"c{i}"))
    c0 = time.thread_time()
    sim.run(DURATION, done=(lambda t, truth: t > 1e9 and truth.p_W[2] < 0.0) if done else None)
    return time.thread_time() - c0


def bench_overhead() -> None:
    square = [(Software, 250.0), (Software, 250.0), (Software, 250.0), (Software, 500.0)]
    configs = [
        ("no components", [], False),
        ("rate loop 500 Hz", [(Software, 500.0)], False),
        ("square: 500 + 3 x 250 Hz, done", square, True),
        (
            "+ estimator 200 Hz, IMU 200 Hz and pose 10 Hz (truth readers)",
            [(TruthReader, 200.0), (TruthReader, 10.0), (Software, 200.0), *square],
            True,
        ),
    ]
    phys = min(physics_alone() for _ in range(REPEATS))
    print(
        f"Simulator overhead per 1 kHz physics node (CPU, best of {REPEATS}; physics alone "
        f"{1e6 * phys / (DURATION * 1000):.2f} us/step)"
    )
    for name, spec, done in configs:
        cpu = min(simulated(spec, done) for _ in range(REPEATS))
        print(f"  {name:64s} {1e6 * (cpu - phys) / (DURATION * 1000):6.2f} us/node")


def bench_square_mocap() -> None:
    from cufund.scenarios import load_scenario
    from cufund.scenarios.build import build_simulation, run_built

    cfg = load_scenario("square_mocap")
    run_built(build_simulation(cfg))  # the first run pays one-time costs
    best = None
    for _ in range(3):
        c0 = time.process_time()
        built = build_simulation(cfg)
        run = run_built(built)
        cpu = time.process_time() - c0
        if best is None or cpu < best[0]:
            best = (cpu, run, built)
    cpu, run, built = best
    sim_s = run.metrics["sim_time_s"]
    print(
        f"square_mocap: {sim_s:.2f} s simulated in {cpu:.3f} s process CPU ({sim_s / cpu:.1f}x real time per CPU "
        f"second); wall per call of each component:"
    )
    res = run.result
    calls = {s["name"]: s["rate_hz"] * sim_s for s in built.simulator.schedule}
    for name, seconds in res.component_seconds.items():
        n = calls.get(name, sim_s * 1000.0 if name == "physics" else 0.0)
        per = f"{1e6 * seconds / n:7.1f} us/call" if n else ""
        print(f"  {name:22s} {seconds:7.4f} s {per}")


if __name__ == "__main__":
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    bench_overhead()
    bench_square_mocap()
