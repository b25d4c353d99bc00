"""Learning environments: env-steps/s of Hover-v0 (state only) at 4096 envs for cufund, crazyflow and
gym-pybullet-drones, and 64 x 64 depth frames/s of ForestAvoid-v0, in one run on this machine (issue 28). Not a
timed test: figures for the closing note.

    .venv/bin/python benchmarks/bench_envs.py [--envs 4096] [--seconds 3]

cufund: ``gymnasium.make_vec("cufund/Hover-v0", num_envs=N)`` (one RK4 step of the full rigid-body model with motor
lag per 10 ms env step; observation, reward, termination and autoreset in C++), stepped with random actions,
``rotor_speeds`` and ``thrust_rates`` (cufund's rate loop per env). crazyflow (PyPI ``crazyflow``, JAX on CPU, the
``bench`` extra): its ``DroneReachPos-v0`` vector env (the hover-at-a-goal task) at its defaults (500 Hz env step,
one explicit Euler step of its fitted ``so_rpy`` model, attitude actions), and also with its ``first_principles``
rigid-body dynamics; jitted before timing, results blocked on. gym-pybullet-drones: measured only if it imports.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import gymnasium
import numpy as np


def rate(step: Callable[[], None], n_envs: int, seconds: float) -> float:
    """Env-steps/s of ``step`` (one step of every env), after a warm-up, over at least ``seconds``."""
    for _ in range(5):
        step()
    k, t0 = 0, time.perf_counter()
    while True:
        step()
        k += 1
        dt = time.perf_counter() - t0
        if dt >= seconds and k >= 10:
            return k * n_envs / dt


def rates(step: Callable[[], None], n_envs: int, seconds: float) -> tuple[float, float]:
    """(env-steps per wall second, env-steps per CPU second of this process, all its threads): on a machine shared
    with other work, the second is what the code costs, the first what the machine gave it."""
    c0, k0 = time.process_time(), time.perf_counter()
    wall = rate(step, n_envs, seconds)
    steps = wall * (time.perf_counter() - k0)  # the warm-up's few steps are within the error
    return wall, steps / (time.process_time() - c0)


def cufund_rate(n: int, seconds: float, **kw: object) -> tuple[float, float]:
    import cufund.envs  # noqa: F401

    env = gymnasium.make_vec("cufund/Hover-v0", num_envs=n, **kw)
    env.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-0.3, 0.3, (16, n, 4))
    i = [0]

    def step() -> None:
        env.step(acts[i[0] % 16])
        i[0] += 1

    return rates(step, n, seconds)


def crazyflow_rate(n: int, seconds: float, dynamics: str | None = None) -> tuple[float, float] | str:
    try:
        import crazyflow.envs  # noqa: F401
        import jax
    except Exception as e:
        return f"not installed ({type(e).__name__}: {e}); pip install '.[bench]'"
    kw = {} if dynamics is None else {"dynamics": dynamics}
    env = gymnasium.make_vec("DroneReachPos-v0", num_envs=n, device="cpu", **kw)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high
    acts = [jax.numpy.asarray(rng.uniform(low, high).astype(np.float32)) for _ in range(16)]
    i = [0]

    def step() -> None:
        obs, rew, *_ = env.step(acts[i[0] % 16])
        jax.block_until_ready(rew)
        i[0] += 1

    return rates(step, n, seconds)


def pybullet_drones_rate() -> str:
    try:
        import gym_pybullet_drones  # noqa: F401
    except Exception as e:
        return f"not measured: gym-pybullet-drones does not import here ({type(e).__name__}); it is not on PyPI"
    return "installed, but its envs step one drone per env in Python (no batched env): not measured"


def forest_depth_rates(n: int, seconds: float) -> tuple[float, float, float, float, float, float]:
    """ForestAvoid-v0 with its 64 x 64 depth camera (28B): 64 x 64 frames/s of whole env steps (dynamics, state,
    reward, collisions and one batched depth cast for every env) and of the batched cast alone; then the same per
    second of this process's CPU time (both threads' seconds summed: the machine's other load left out)."""
    import cufund.envs  # noqa: F401

    env = gymnasium.make_vec("cufund/ForestAvoid-v0", num_envs=n)
    env.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-0.3, 0.3, (16, n, 4))
    i = [0]

    def step() -> None:
        env.step(acts[i[0] % 16])
        i[0] += 1

    c0 = time.process_time()
    k0 = i[0]
    steps = rate(step, n, seconds)
    steps_cpu = (i[0] - k0) * n / (time.process_time() - c0)
    fa = env.unwrapped  # cufund's own ForestAvoidEnv (its vector_entry_point)
    p, q = np.asarray(fa.batch.p).copy(), np.asarray(fa.batch.q).copy()
    calls = [0]

    def cast_once() -> None:
        fa.sensor.observe(p, q)
        calls[0] += 1

    c0 = time.process_time()
    cast = rate(cast_once, n, seconds)
    cast_cpu = calls[0] * n / (time.process_time() - c0)
    # The same poses cast by Embree (the caster of worlds that are not trunks and ground; ForestAvoid's before 28B).
    from cufund.envs.observation_sensors import BatchRangeSensor

    embree = BatchRangeSensor(fa.world.raycast_scene, fa.sensor.spec)
    calls[0] = 0

    def embree_once() -> None:
        embree.observe(p, q)
        calls[0] += 1

    c0 = time.process_time()
    emb = rate(embree_once, n, seconds)
    emb_cpu = calls[0] * n / (time.process_time() - c0)
    return steps, cast, steps_cpu, cast_cpu, emb, emb_cpu


def depth_figures(n: int, seconds: float) -> None:
    steps, cast, steps_cpu, cast_cpu, emb, emb_cpu = forest_depth_rates(n, seconds)
    print(f"ForestAvoid-v0 depth 64x64, {n} envs, load {os.getloadavg()[0]:.1f}")
    print(f"  env steps with depth                     {steps / 1e3:8.1f} k frames/s")
    print(f"  batched depth cast alone (analytic)      {cast / 1e3:8.1f} k frames/s ({cast * 4096 / 1e6:.0f} M rays/s)")
    print(f"  the same poses cast by Embree            {emb / 1e3:8.1f} k frames/s ({emb * 4096 / 1e6:.0f} M rays/s)")
    print(
        f"  per CPU second: env steps {steps_cpu / 1e3:.1f} k frames, cast alone {cast_cpu / 1e3:.1f} k frames, "
        f"Embree {emb_cpu / 1e3:.1f} k frames"
    )
    print(f"  target: >= 50 k frames/s ({'met' if steps >= 50e3 else 'NOT met'})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=4096)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--depth-envs", type=int, default=1024, help="ForestAvoid-v0 envs for the depth figures")
    ap.add_argument("--depth-only", action="store_true", help="only the ForestAvoid-v0 depth figures")
    args = ap.parse_args()
    if args.depth_only:
        depth_figures(args.depth_envs, args.seconds)
        return
    n = args.envs
    print(f"Hover-v0 state only, {n} envs, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    ours, ours_cpu = cufund_rate(n, args.seconds)
    print(
        f"  cufund Hover-v0 rotor_speeds             {ours / 1e6:8.2f} M env-steps/s  ({ours_cpu / 1e6:.2f} M per CPU s)"
    )
    tr, tr_cpu = cufund_rate(n, args.seconds, action_mode="thrust_rates")
    print(f"  cufund Hover-v0 thrust_rates             {tr / 1e6:8.2f} M env-steps/s  ({tr_cpu / 1e6:.2f} M per CPU s)")
    for label, dyn in (("crazyflow DroneReachPos-v0 so_rpy", None), ("crazyflow first_principles", "first_principles")):
        cf = crazyflow_rate(n, args.seconds, dyn)
        if isinstance(cf, str):
            print(f"  {label:<40} {cf}")
            continue
        print(
            f"  {label:<40} {cf[0] / 1e6:8.2f} M env-steps/s  ({cf[1] / 1e6:.2f} M per CPU s)"
            f"   cufund/crazyflow = {ours / cf[0]:5.2f}x wall, {ours_cpu / cf[1]:5.2f}x per CPU s"
        )
    print(f"  gym-pybullet-drones                      {pybullet_drones_rate()}")
    print(
        f"  targets: >= 10 M env-steps/s ({'met' if ours >= 10e6 else 'NOT met'} on the wall clock; "
        f"2 idle cores at this CPU cost: {2 * ours_cpu / 1e6:.1f} M), >= 2x crazyflow"
    )
    depth_figures(args.depth_envs, args.seconds)


if __name__ == "__main__":
    main()
