"""Benchmark against RotorPy 3.0.0, in one run (not a test; prints ratios).

1. Real-time factor of the square case study: cufund (C++ RK4 physics + Python controllers on the lockstep
   clock) vs RotorPy's ``Environment`` with its ``SE3Control``, same vehicle (the Crazyflie: cufund's preset
   has RotorPy's numbers), same reference (take-off, min-snap square, landing; fed to RotorPy through an
   adapter), same rates: physics 1 kHz, controller and setpoints 1 kHz (RotorPy runs its controller once per
   simulator step; its Environment also samples its default IMU). cufund at its default rates (controller
   500 Hz, setpoints 250 Hz), and at matched rates with the inertial and navigation sensors of the
   ``square_sensors`` scenario attached, are printed too.
2. Minimum-snap solve time for 5, 20 and 100 random waypoints: cufund's ``MinimumSnapTrajectory`` (automatic
   time allocation: two banded solves and a speed/acceleration check) vs RotorPy's ``MinSnap`` (its own time
   allocation and cvxopt QPs), and cufund given RotorPy's segment times (one solve).

Run: ``.venv/bin/python benchmarks/bench_square.py``
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np


def bench_real_time_factor() -> None:
    from rotorpy.controllers.quadrotor_control import SE3Control
    from rotorpy.environments import Environment
    from rotorpy.vehicles.crazyflie_params import quad_params
    from rotorpy.vehicles.multirotor import Multirotor

    from cufund.scenarios import RatesConfig, build_reference, load_scenario, run_scenario

    base = load_scenario("square")
    base = base.replace(vehicle="crazyflie", controller=dataclasses.replace(base.controller, kind="geometric"))
    same = base.replace(rates=RatesConfig(physics_hz=1000, trajectory_hz=1000, geometric_hz=1000))

    def best(cfg, repeats=3):
        """The fastest of a few runs (the first run in a process pays one-time costs; the VM's speed drifts)."""
        return min((run_scenario(cfg) for _ in range(repeats)), key=lambda r: r.metrics["wall_time_s"])

    ours_same = best(same)
    ours_default = best(base)
    sensors = load_scenario("square_sensors").sensors  # ICM-42688-P IMU, magnetometer, MS5611, u-blox M8N
    ours_sensors = best(same.replace(sensors=sensors))
    reference, _ = build_reference(base.trajectory)

    class Adapter:
        """cufund's reference as RotorPy's flat outputs."""

        def update(self, t: float) -> dict:
            s = reference.sample(t)
            z = np.zeros(3)
            return {
                "x": s.p_W[0],
                "x_dot": s.v_W[0],
                "x_ddot": s.a_W[0],
                "x_dddot": s.j_W[0],
                "x_ddddot": z,
                "yaw": float(s.yaw[0]),
                "yaw_dot": float(s.yaw_rate[0]),
                "yaw_ddot": 0.0,
            }

    x0 = {
        "x": np.zeros(3),
        "v": np.zeros(3),
        "q": np.array([0.0, 0.0, 0.0, 1.0]),
        "w": np.zeros(3),
        "wind": np.zeros(3),
        "rotor_speeds": np.full(4, 1788.53),
    }
    t_final = ours_same.result.sim_time_s
    env = Environment(
        vehicle=Multirotor(quad_params, initial_state=x0),
        controller=SE3Control(quad_params),
        trajectory=Adapter(),
        sim_rate=1000,
    )
    t0 = time.perf_counter()
    res = env.run(t_final=t_final)
    wall = time.perf_counter() - t0
    rp_rtf = t_final / wall
    p_err = np.linalg.norm(res["state"]["x"] - np.array([Adapter().update(t)["x"] for t in res["time"]]), axis=1)
    print("Square case study, Crazyflie, geometric/SE3 controller, physics 1 kHz")
    print(
        f"  RotorPy Environment   (control 1 kHz): {t_final:6.2f} s simulated in {wall:7.2f} s  RTF {rp_rtf:7.2f}"
        f"  (exit {res['exit'].value}; RMSE vs reference {np.sqrt(np.mean(p_err**2)):.4f} m)"
    )
    for label, run in (
        ("cufund (control 1 kHz)      ", ours_same),
        ("cufund (control 500 Hz, default)", ours_default),
        ("cufund (control 1 kHz) + IMU, magnetometer, barometer, GPS", ours_sensors),
    ):
        m = run.metrics
        print(
            f"  {label}: {m['sim_time_s']:6.2f} s simulated in {m['wall_time_s']:7.2f} s  RTF {m['real_time_factor']:7.2f}"
            f"  -> {m['real_time_factor'] / rp_rtf:6.1f}x RotorPy  (status {m['status']}; min-snap RMSE "
            f"{m['tracking_rmse_m']:.4f} m)"
        )


def bench_min_snap() -> None:
    from rotorpy.trajectories.minsnap import MinSnap

    from cufund.planning import MinimumSnapTrajectory

    print("Minimum-snap solve time (best of repeats)")
    rng = np.random.default_rng(0)
    for n in (5, 20, 100):
        w = np.cumsum(rng.uniform(-2, 2, (n, 3)), axis=0)

        def best(fn, repeats):
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                out = fn()
                times.append(time.perf_counter() - t0)
            return min(times), out

        t_rp, rp = best(lambda: MinSnap(w, verbose=False), 3 if n == 100 else 10)
        t_ours, _ = best(lambda: MinimumSnapTrajectory(w), 20)
        t_given, ours = best(lambda: MinimumSnapTrajectory(w, durations=rp.delta_t), 20)
        print(
            f"  {n:3d} waypoints: RotorPy {1e3 * t_rp:8.2f} ms | cufund auto times {1e3 * t_ours:6.2f} ms "
            f"({t_rp / t_ours:6.0f}x) | cufund given RotorPy's times {1e3 * t_given:6.2f} ms ({t_rp / t_given:6.0f}x)"
        )


if __name__ == "__main__":
    bench_min_snap()
    bench_real_time_factor()
