"""``cufund dataset SCENARIO --out DIR --frames N [--seed S] [--randomisation FILE] [--views course]``: renders a labelled detection dataset of a
scenario's world (YOLO and COCO, with domain randomisation; :mod:`cufund.perception.dataset`). Exit codes: 0
written, 2 invalid configuration or usage (a message naming the field), 130 interrupted."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from cufund.core.config import ConfigError

from .arguments import add_overrides

__all__ = ["add_arguments", "run"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="a built-in scenario name or a YAML file (its world is rendered)")
    p.add_argument("--out", type=Path, required=True, help="dataset folder (created; must be empty if it exists)")
    p.add_argument("--frames", type=int, default=100, help="images rendered (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random draw (default 0)")
    p.add_argument(
        "--scatter",
        type=int,
        default=0,
        help="labelled objects (people, cars, landing pads, gates) placed at random on free ground first (default 0)",
    )
    p.add_argument(
        "--classes",
        default=None,
        help="comma-separated object labels that are classes, in index order "
        "(default tunnel_frame,gate,landing_pad,person,car)",
    )
    p.add_argument("--width", type=int, default=640, help="image width [px] (default 640)")
    p.add_argument("--height", type=int, default=480, help="image height [px] (default 480)")
    p.add_argument(
        "--hfov-deg", type=float, default=None, help="horizontal field of view [deg] (default: D435 RGB's 55)"
    )
    p.add_argument(
        "--randomisation",
        type=Path,
        default=None,
        help="a YAML mapping of randomisation ranges overriding the defaults, e.g. height_m: [8, 16] "
        "(keys: cufund.perception.dataset.Randomisation)",
    )
    p.add_argument(
        "--views",
        choices=("random", "course"),
        default="random",
        help="random: views around single labelled objects (default); course: views as the vehicle has them flying "
        "a tunnel_course world's frames, in the flight camera (the stereo_camera rig's 640 x 480, fx = fy = 400 px, "
        "unless --width/--height/--hfov-deg say otherwise)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress line")
    add_overrides(p, help="override a scenario field by its dotted key, e.g. --set world.seed=3 (repeatable)")


def run(args: argparse.Namespace) -> int:
    try:
        from cufund.core.config import from_dict, load_yaml
        from cufund.perception.dataset import DatasetParams, Randomisation, write_dataset
        from cufund.scenarios.run_folder import world_of
        from cufund.scenarios.schema import load_scenario, parse_overrides
        from cufund.sensors.camera import CameraIntrinsics, d435_rgb
        from cufund.worlds.labelled_objects import CLASSES, scatter

        config = load_scenario(args.scenario, parse_overrides(args.overrides))
        world = world_of(config)
        if world is None:
            raise ConfigError(f"scenario {args.scenario!r} has no world to render")
        if args.scatter:
            rng = np.random.default_rng([int(args.seed), 0x5CA7])  # its own stream: the frames' draws unchanged
            scatter(world, rng, int(args.scatter))
        classes = CLASSES if args.classes is None else tuple(c.strip() for c in args.classes.split(","))
        randomisation = Randomisation()
        if args.randomisation is not None:
            doc = load_yaml(args.randomisation)
            randomisation = from_dict(Randomisation, {} if doc is None else doc, f"{args.randomisation}: randomisation")
        params = DatasetParams(
            frames=args.frames, seed=args.seed, classes=classes, randomisation=randomisation, views=args.views
        )
        course = None
        if args.views == "course":
            from cufund.missions.tunnel_kind import course_of

            layout = course_of(config)
            if layout is None:
                raise ConfigError(
                    f"--views course needs a scenario on the tunnel_course world; {args.scenario!r} is not"
                )
            course = layout.frames
        if args.views == "course" and args.hfov_deg is None and (args.width, args.height) == (640, 480):
            from cufund.sensors.kinds import StereoCameraParams

            intrinsics = StereoCameraParams().intrinsics  # the flight camera (perception: camera's rig)
        elif args.hfov_deg is None and (args.width, args.height) == (640, 480):
            intrinsics = d435_rgb()
        else:
            hfov = 55.0 if args.hfov_deg is None else args.hfov_deg
            intrinsics = CameraIntrinsics.from_fov(args.width, args.height, np.deg2rad(hfov))
        progress = None
        if not args.no_progress and sys.stderr.isatty():

            def progress(k: int) -> None:
                print(f"\rframes {k}/{args.frames}", end="" if k < args.frames else "\n", file=sys.stderr)

        summary = write_dataset(
            world, args.out, params, intrinsics, source=str(args.scenario), progress=progress, course=course
        )
    except KeyboardInterrupt:
        print("cufund: interrupted", file=sys.stderr)
        return 130
    except (ConfigError, ValueError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return 2
    print(json.dumps(summary, indent=2))
    print(f"dataset folder: {args.out.resolve()}")
    return 0
