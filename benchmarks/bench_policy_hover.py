"""How well an exported hover policy holds its point (issue 28): 100 random starts of Hover-v0 (the task's spawn
box, tilt, speed and spin; the policy's vehicle and action mode) flown 10 s each by the ONNX policy through
onnxruntime (a timed-reference Waypoints-v0 policy flies the same starts with Hover-v0's point as its one waypoint).
Prints how many stay up, the per-start RMS position error over the 10 s (the approach included) and,
over the last 5 s of the starts that stayed up, the mean/RMS/worst distance to the point and the share of starts
whose mean is below 5 cm (the issue's target).

Run: `.venv/bin/python benchmarks/bench_policy_hover.py [POLICY_DIR]` (default: the shipped
python/cufund/envs/policies/hover_cu_astro). Train one with `cufund train ... --out DIR` first to measure it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from cufund.control.policy_manifest import PolicyManifest
from cufund.envs.train import make_env, onnx_actor

SHIPPED = Path(__file__).resolve().parents[1] / "python/cufund/envs/policies/hover_cu_astro"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("policy", nargs="?", type=Path, default=SHIPPED)
    ap.add_argument("--starts", type=int, default=100)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=2024)
    args = ap.parse_args()
    m = PolicyManifest.read(args.policy / "policy.yaml")
    act = onnx_actor(args.policy / "policy.onnx")
    n = args.starts
    kwargs = {"action_mode": m.action_mode, "vehicle": m.vehicle, "episode_s": args.seconds}
    task = "cufund/Hover-v0"
    if m.lookahead_s > 0:  # a timed-reference waypoints policy: Hover-v0's point, spawn box and bound as its one
        # waypoint (the reference rests there, every target block the point)
        hover = make_env(task, 1, kwargs).config
        task = "cufund/Waypoints-v0"
        kwargs.update(
            targets=[list(hover.targets[0])],
            n_ahead=m.n_targets,
            lookahead_s=m.lookahead_s,
            segment_s=[1.0, 1.0],
            **{
                k: getattr(hover, k) for k in ("spawn_extent", "spawn_speed", "spawn_tilt_deg", "spawn_rate", "bound_m")
            },
        )
    env = make_env(task, n, kwargs)
    obs, _ = env.reset(seed=args.seed)
    point = np.asarray(env.config.targets[0][:3])
    steps = env.config.max_steps
    err = np.full((steps, n), np.nan)
    up = np.ones(n, dtype=bool)
    for k in range(steps):
        obs, _r, term, _trunc, _ = env.step(act(obs))
        err[k] = np.where(up, np.linalg.norm(np.asarray(env.batch.p) - point, axis=1), np.nan)
        up &= ~np.asarray(term)
    env.close()
    rms_all = np.sqrt(np.nanmean(err**2, axis=0))
    last = err[steps // 2 :, up]
    print(f"policy {args.policy} ({m.task}, {m.vehicle}, {m.action_mode}, {m.env_steps} training steps)")
    print(f"  stayed up {args.seconds:g} s        {int(up.sum())}/{n}")
    print(f"  RMS error per start      median {100 * np.median(rms_all):.1f} cm (approach included)")
    if up.any():
        print(
            f"  last half, survivors     mean {100 * last.mean():.1f} cm, RMS {100 * np.sqrt(np.mean(last**2)):.1f} cm, "
            f"worst {100 * last.max():.1f} cm; mean < 5 cm in {100 * np.mean(last.mean(axis=0) < 0.05):.0f} % of starts"
        )


if __name__ == "__main__":
    main()
