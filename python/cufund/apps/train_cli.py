"""``cufund train TASK --algo ppo --steps N --out DIR``: trains a policy on a cufund task with skrl's PPO (JAX on
CPU) and exports it to ONNX (:mod:`cufund.envs.train`). Exit codes: 0 trained and exported, 2 invalid
configuration or usage (a message naming the field), 130 interrupted."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

import yaml

from cufund.core.config import ConfigError

__all__ = ["add_arguments", "run"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("task", nargs="?", help="task: cufund/Hover-v0, Hover, Waypoints, Gates, ... (or set in --config)")
    p.add_argument("--algo", choices=("ppo",), default=None, help="RL algorithm (default ppo)")
    p.add_argument("--steps", type=int, default=None, help="total environment steps over all envs (default 1e6)")
    p.add_argument("--out", type=Path, required=True, help="folder for policy.onnx, policy.yaml and the logs")
    p.add_argument("--num-envs", type=int, default=None, help="vehicles simulated side by side (default 256)")
    p.add_argument("--seed", type=int, default=None, help="seed of every stream (default 0)")
    p.add_argument("--config", type=Path, default=None, help="a YAML of TrainConfig keys (options override it)")
    p.add_argument(
        "--env",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="task override passed to gymnasium.make_vec, VALUE as YAML (e.g. action_mode=thrust_rates, "
        "vehicle=cu_astro); repeatable",
    )
    p.add_argument("--eval-envs", type=int, default=100, help="episodes of the random/trained comparison (0: none)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _env_kwargs(items: list[str]) -> dict:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--env expects KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as e:
            raise ConfigError(f"--env {key}: the value is not YAML ({e})") from None
    return out


def run(args: argparse.Namespace) -> int:
    try:
        from cufund.envs.train import TrainConfig, train

        env_kwargs = _env_kwargs(args.env)
        overrides = {"task": args.task, "algo": args.algo, "steps": args.steps, "num_envs": args.num_envs}
        overrides["seed"] = args.seed
        if args.config is not None:
            cfg = TrainConfig.from_yaml(args.config, **overrides)
            if env_kwargs:
                cfg = TrainConfig(**{**cfg.to_dict(), "env_kwargs": {**cfg.env_kwargs, **env_kwargs}})
        else:
            if args.task is None:
                raise ConfigError("cufund train: give a TASK (e.g. Hover) or a --config naming one")
            kw = {k: v for k, v in overrides.items() if v is not None}
            cfg = TrainConfig(**kw, env_kwargs=env_kwargs)
        if args.eval_envs < 0:
            raise ConfigError(f"--eval-envs must be >= 0, got {args.eval_envs}")
        result, _agent = train(cfg, args.out, progress=not args.no_progress, evaluate_envs=args.eval_envs)
    except ConfigError as e:
        print(f"cufund train: {e}", file=sys.stderr)
        return 2
    except (ValueError, TypeError, OSError) as e:
        print(f"cufund train: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("cufund train: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
    summary = {
        "task": result.manifest.task,
        "action_mode": result.manifest.action_mode,
        "env_steps": result.env_steps,
        "wall_s": round(result.wall_s, 2),
        "mean_return_random": result.mean_return_random,
        "mean_return": result.mean_return,
        "policy": str(result.onnx_path),
    }
    (Path(args.out) / "train_result.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return 0
