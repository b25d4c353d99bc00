"""Cost of the world's effects on the square's real-time factor (issue 30's benchmark, not a test; prints ratios).

The square case study (cu_astro, PID, 1 kHz physics) flown calm and with each term alone and all together:

- turbulence: ``atmosphere: {kind: dryden, wind_20ft_mps: 3}`` (evaluated in C++ at 200 Hz);
- ground effect: ``ground_effect: true`` (the square has no world: the ground plane, set once);
- battery: ``vehicle.battery: {cells: 4, capacity_mah: 850}`` (issue 30's energy model);
- all three.

Each configuration runs ``--repeats`` times in this process, interleaved, and keeps its fastest run (the first run
pays one-time costs; other processes share the cores). Prints the real-time factor and its ratio to calm; the
issue's target is a cost of at most 5 % for all three together.

    .venv/bin/python benchmarks/bench_world_effects.py [--repeats 7]
"""

from __future__ import annotations

import argparse

CONFIGS = {
    "calm": [],
    "turbulence": ["atmosphere.kind=dryden", "atmosphere.wind_20ft_mps=3", "atmosphere.seed=1"],
    "ground effect": ["ground_effect=true"],
    "battery": ["vehicle.battery.cells=4", "vehicle.battery.capacity_mah=850"],
}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=7, help="runs per configuration (the fastest is kept)")
    ap.add_argument("--no-battery", action="store_true", help="leave the battery out (before it exists)")
    args = ap.parse_args()

    from cufund.core.config import ConfigError
    from cufund.scenarios import load_scenario, run_scenario

    base = load_scenario("square")
    configs = dict(CONFIGS)
    if args.no_battery:
        configs.pop("battery")
    configs["all"] = [o for k, v in configs.items() if k != "calm" for o in v]
    scenarios = {}
    for name, overrides in configs.items():
        try:
            scenarios[name] = base.with_overrides(overrides)
        except ConfigError as e:
            print(f"{name}: skipped ({e})")
    best: dict[str, float] = {}
    status: dict[str, str] = {}
    for _ in range(args.repeats):
        for name, cfg in scenarios.items():
            m = run_scenario(cfg).metrics
            status[name] = m["status"]
            best[name] = min(best.get(name, float("inf")), m["wall_time_s"] / m["sim_time_s"])
    calm = best["calm"]
    print(f"square, fastest of {args.repeats} runs each: real-time factor (ratio to calm; cost = 1 - ratio)")
    for name, s_per_s in best.items():
        rtf = 1.0 / s_per_s
        print(
            f"  {name:14s} RTF {rtf:7.1f}   ratio {calm / s_per_s:.3f}   cost {100 * (1 - calm / s_per_s):+5.1f} %"
            f"   ({status[name]})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
