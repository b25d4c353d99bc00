"""Dynamics throughput against RotorPy's Multirotor.step, in one run, at the same dt (1 ms).

Prints single-vehicle steps/s, batched vehicle-steps/s and their ratios to RotorPy's steps/s.
Targets (issue 2, 2 cores): single vehicle >= 100x RotorPy; a batch of 4096 >= 10 M vehicle-steps/s.
Run: `make bench` or `.venv/bin/python benchmarks/bench_dynamics.py`.
"""

from __future__ import annotations

import os
import time

import numpy as np

import cufund

DT = 1e-3


def rate(fn, min_seconds: float = 1.0) -> float:
    """Calls fn(k) for growing k until it takes min_seconds; returns calls per second."""
    k = 1
    while True:
        t0 = time.perf_counter()
        fn(k)
        wall = time.perf_counter() - t0
        if wall >= min_seconds:
            return k / wall
        k *= 2


def rotorpy_steps_per_s() -> float:
    from rotorpy.vehicles.crazyflie_params import quad_params
    from rotorpy.vehicles.multirotor import Multirotor

    w_h = cufund.vehicle.presets.crazyflie().hover_rotor_speed
    state = {
        "x": np.array([0.0, 0.0, 1.0]),
        "v": np.zeros(3),
        "q": np.array([0.0, 0.0, 0.0, 1.0]),
        "w": np.zeros(3),
        "wind": np.zeros(3),
        "rotor_speeds": np.full(4, w_h),
    }
    vehicle = Multirotor(quad_params, initial_state=state, aero=True)
    control = {"cmd_motor_speeds": np.full(4, w_h)}

    def run(k: int) -> None:
        s = state
        for _ in range(k):
            s = vehicle.step(s, control, DT)

    return rate(run)


def single_steps_per_s() -> float:
    params = cufund.vehicle.presets.crazyflie()
    quad = cufund.Quadrotor(params)
    quad.hover((0.0, 0.0, 1.0))
    cmd = np.full(4, params.hover_rotor_speed)

    def run(k: int) -> None:
        step = quad.step
        for _ in range(k):
            step(DT, cmd)

    return rate(run)


def batch_vehicle_steps_per_s(n: int) -> float:
    params = cufund.vehicle.presets.crazyflie()
    batch = cufund.QuadrotorBatch(params, n)
    batch.hover(np.c_[np.zeros((n, 2)), np.full(n, 10.0)])
    cmd = np.full((n, 4), params.hover_rotor_speed) * (1 + 1e-3 * np.random.default_rng(0).standard_normal((n, 4)))

    def run(k: int) -> None:
        for _ in range(k):
            batch.step(DT, cmd)

    return n * rate(run)


def main() -> None:
    print(f"cufund {cufund.__version__} dynamics benchmark, dt = {DT * 1e3:g} ms, {os.cpu_count()} cores, Crazyflie")
    ref = rotorpy_steps_per_s()
    print(f"  RotorPy Multirotor.step (scipy RK45)   {ref:14,.0f} steps/s")
    single = single_steps_per_s()
    print(
        f"  cufund.Quadrotor.step                   {single:14,.0f} steps/s     {single / ref:8.0f}x RotorPy"
        "   (target >= 100x)"
    )
    for n in (4096, 100_000):
        b = batch_vehicle_steps_per_s(n)
        print(
            f"  cufund.QuadrotorBatch.step, n = {n:<7} {b:14,.0f} vehicle-steps/s {b / ref:8.0f}x RotorPy"
            + ("   (target >= 10 M/s)" if n == 4096 else "")
        )


if __name__ == "__main__":
    main()
