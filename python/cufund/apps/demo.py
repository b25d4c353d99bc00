"""`make demo` until the simulator lands: open-loop flights of the three presets and a batch of 4096.

Run with ``python -m cufund.apps.demo``.
"""

from __future__ import annotations

import time

import numpy as np

from cufund.vehicle import presets
from cufund.vehicle.quadrotor import Quadrotor, QuadrotorBatch


def main() -> None:
    for params in (presets.crazyflie(), presets.iris(), presets.cu_astro()):
        quad = Quadrotor(params)
        omega_h = params.hover_rotor_speed
        cmd = np.full(4, 1.05 * omega_h)  # 10 % more thrust than the weight: climbs from the ground
        steps = 2000
        t0 = time.perf_counter()
        for _ in range(steps):
            quad.step(1e-3, cmd)
        wall = time.perf_counter() - t0
        print(
            f"{params.name:>9}: hover {omega_h:7.1f} rad/s; after 2 s at 1.05x hover speed "
            f"z = {quad.state.p[2]:.3f} m, v_z = {quad.state.v[2]:.3f} m/s "
            f"({steps / wall / 1e3:.0f} k steps/s single vehicle)"
        )

    n = 4096
    batch = QuadrotorBatch(presets.crazyflie(), n)
    rng = np.random.default_rng(0)
    batch.hover(np.c_[rng.uniform(-5, 5, (n, 2)), np.full(n, 2.0)])
    cmd = batch.params.hover_rotor_speed * (1.0 + 0.01 * rng.standard_normal((n, 4)))
    t0 = time.perf_counter()
    for _ in range(500):
        batch.step(1e-3, cmd)
    wall = time.perf_counter() - t0
    tilt = 2 * np.degrees(np.arccos(np.clip(np.abs(batch.q[:, 0]), 0, 1)))
    print(
        f"batch of {n} Crazyflies, 0.5 s with 1 % random rotor-speed errors: mean rotation {tilt.mean():.1f} deg, "
        f"{n * 500 / wall / 1e6:.1f} M vehicle-steps/s"
    )


if __name__ == "__main__":
    main()
