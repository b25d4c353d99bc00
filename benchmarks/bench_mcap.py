"""Benchmark of run logs (not a test; prints figures and ratios).

1. Writing N messages of each type with :class:`cufund.logs.McapLogger` (write calls, main-thread CPU and wall;
   the writer thread's CPU beside it) vs the official Python path for the same bytes: ``mcap_ros2``'s
   ``Writer.write_message`` with the same ros2msg schema (per-message CDR serialisation into ``mcap``'s writer,
   zstd chunks). The messages are built before the timed loops (building one costs more than logging it).
2. The square case study (``cufund run square``'s pipeline, in process) with and without ``run.mcap``:
   alternating runs, medians of wall time, of the simulation thread's CPU time and of the process's CPU time
   (the writer thread included), and the overhead of each in percent (the issue's bound: <= 10 % of wall time),
   with the load average beside them.
3. Reading the square's log back with :func:`cufund.logs.read_mcap` (messages per second).
4. ``--runs``: the run logs of ``cufund run square`` and ``cufund run tunnel`` as written
   (:func:`cufund.scenarios.run_folder.run_into_folder`, no figures): the file's size, and the writing cost as the
   median wall and process-CPU time of alternating runs with and without the log (relative to the run's wall
   time: the issue's bound is <= 10 %); then the same ROS 2 messages (every CDR channel of the log, raw bytes) as
   a ROS 2 bag written with ``rosbags`` (sqlite3 storage, uncompressed, as ``ros2 bag record`` writes by
   default): its size and writing time. ``--tree DIR`` runs part 4 on another cufund source tree (``DIR/cufund``)
   instead of the installed one: the writer before a change, e.g. ``git archive <commit> python/cufund | tar -x
   -C /tmp/old`` with the installed ``_core*.so`` copied into ``/tmp/old/python/cufund`` (the old tree then needs
   the same compiled core).

Run: ``.venv/bin/python benchmarks/bench_mcap.py [--repeats 7] [--square-only]``; ``--runs [--tree DIR]``.
Instruction counts (load-independent): ``valgrind --tool=callgrind .venv/bin/python benchmarks/bench_mcap.py
--once without`` and ``--once with`` (one square run each; the difference is the log's cost, both threads).
"""

from __future__ import annotations

import sys

if "--tree" in sys.argv:  # another cufund tree (the writer before a change): bypass the editable install's finder
    sys.path.insert(0, sys.argv[sys.argv.index("--tree") + 1])
    sys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]

import argparse
import gc
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from cufund import messages as M
from cufund.logs import McapLogger, read_mcap
from cufund.logs.codecs import codec_for

N = 20_000


def _makers(rng: np.random.Generator) -> dict[str, object]:
    a = rng.normal(size=(8, 4))
    return {
        "Odometry (truth)": lambda t: M.Odometry(t, a[0, :3] + t, a[1, :3], a[2], a[3, :3], a[4, :3], a[5, :3]),
        "Imu": lambda t: M.Imu(t, a[0, :3] + t, a[1, :3]),
        "TrajectorySetpoint": lambda t: M.TrajectorySetpoint(t, a[0, :3] + t, a[1, :3], a[2, :3], a[3, :3], 0.1, 0.0),
        "AttitudeSetpoint": lambda t: M.AttitudeSetpoint(t, a[2] + t, 0.3, 0.0),
        "ActuatorCommand": lambda t: M.ActuatorCommand(t, a[6] + t),
        "AirPressure": lambda t: M.AirPressure(t, 101325.0 + t, 1.0, 288.15),
    }


def _as_ros(message: object, layout) -> dict:
    """The message as the dict ``mcap_ros2`` serialises (what a user of the official writer would build)."""
    out = {}
    for attr, ros_name, _, shape, optional in layout.describe():
        value = getattr(message, attr)
        if optional:
            out[f"has_{ros_name}"] = value is not None
            value = np.zeros(int(np.prod(shape))) if value is None else value
        out[ros_name] = value.ravel().tolist() if shape else value
    return out


def bench_types(tmp: Path) -> None:
    from mcap_ros2.writer import Writer as Ros2Writer

    print(
        f"1. logging {N} messages of one type (built beforehand), per message: main-thread CPU, wall, the writer "
        "thread's CPU; mcap_ros2's CPU"
    )
    print(
        f"   {'type':22s} {'cufund us':>10s} {'wall us':>8s} {'writer us':>10s} {'mcap_ros2 us':>13s} {'ratio':>6s} "
        f"{'bytes/msg':>9s}"
    )
    for name, make in _makers(np.random.default_rng(0)).items():
        codec = codec_for("/x", make(0.0))
        messages = [make(k * 1e-3) for k in range(N)]  # built beforehand: building one costs more than logging it
        best = (np.inf, np.inf, np.inf)
        for _ in range(5):
            path = tmp / "types.mcap"
            c0, w0, p0 = time.thread_time(), time.perf_counter(), time.process_time()
            with McapLogger(path) as log:
                write = log.write
                for k, message in enumerate(messages):
                    write("/x", message, k, k)
            c1 = time.thread_time()
            best = min(best, (c1 - c0, time.perf_counter() - w0, time.process_time() - p0 - (c1 - c0)))
        size = path.stat().st_size
        peer = np.inf
        for _ in range(2):
            with open(tmp / "peer.mcap", "wb") as f:
                c0 = time.thread_time()
                writer = Ros2Writer(f)
                schema = writer.register_msgdef(codec.schema_name, codec.schema_data.decode())
                for k, message in enumerate(messages):
                    writer.write_message("/x", schema, _as_ros(message, codec.layout), k, k)
                writer.finish()
                peer = min(peer, time.thread_time() - c0)
        ours, wall = best[0], best[1]
        print(
            f"   {name:22s} {ours / N * 1e6:10.2f} {wall / N * 1e6:8.2f} {best[2] / N * 1e6:10.2f} {peer / N * 1e6:13.2f} "
            f"{peer / ours:5.0f}x {size / N:9.0f}"
        )


def bench_square(tmp: Path, repeats: int) -> Path | None:
    import cufund

    config = cufund.load_scenario("square")
    cufund.run_scenario(config, logger=None)  # warm-up: imports, caches
    walls: dict[str, list[float]] = {"without": [], "with": []}
    threads: dict[str, list[float]] = {"without": [], "with": []}
    processes: dict[str, list[float]] = {"without": [], "with": []}
    path = tmp / "square.mcap"
    load0 = os.getloadavg()[0]
    for _ in range(repeats):
        for kind in ("without", "with"):
            gc.collect()  # the previous run's garbage is not this run's cost
            t0, c0, p0 = time.perf_counter(), time.thread_time(), time.process_time()
            logger = McapLogger(path, {"scenario": "square"}) if kind == "with" else None
            run = cufund.run_scenario(config, logger=logger)
            if logger is not None:
                logger.close()
            walls[kind].append(time.perf_counter() - t0)
            threads[kind].append(time.thread_time() - c0)
            processes[kind].append(time.process_time() - p0)
    load1 = os.getloadavg()[0]
    n = sum(1 for _ in read_mcap(path))
    print(
        f"2. the square ({run.result.sim_time_s:.1f} s simulated, {n} messages logged, {repeats} alternating runs, "
        f"file {path.stat().st_size / 1e6:.1f} MB; load average {load0:.2f} before, {load1:.2f} after, "
        f"{os.cpu_count()} CPUs)"
    )
    for name, values in (("wall", walls), ("simulation-thread CPU", threads), ("process CPU (all threads)", processes)):
        without, with_log = statistics.median(values["without"]), statistics.median(values["with"])
        paired = statistics.median(w / wo for w, wo in zip(values["with"], values["without"], strict=True))
        print(
            f"   {name}: median without log {without:.3f} s, with run.mcap {with_log:.3f} s: "
            f"{(with_log / without - 1) * 100:+.1f} % ({(with_log - without) / n * 1e6:+.2f} us per message); "
            f"median of the {repeats} paired ratios {(paired - 1) * 100:+.1f} %; best {min(values['without']):.3f} s "
            f"vs {min(values['with']):.3f} s ({(min(values['with']) / min(values['without']) - 1) * 100:+.1f} %)"
        )
    return path


def square_once(kind: str) -> None:
    """One square run with or without the log (for callgrind: run both and compare the totals)."""
    import cufund

    config = cufund.load_scenario("square")
    with tempfile.TemporaryDirectory() as tmp:
        logger = McapLogger(Path(tmp) / "square.mcap", {"scenario": "square"}) if kind == "with" else None
        cufund.run_scenario(config, logger=logger)
        if logger is not None:
            logger.close()


def bench_read(path: Path) -> None:
    t0 = time.perf_counter()
    n = sum(1 for _ in read_mcap(path))
    wall = time.perf_counter() - t0
    print(f"3. read_mcap: {n} messages in {wall:.2f} s ({n / wall / 1e3:.0f} k messages/s)")


def write_rosbag(log: Path, bag: Path) -> tuple[int, float, int]:
    """The CDR channels of ``log`` as a ROS 2 bag written with ``rosbags`` (sqlite3, uncompressed): (messages,
    writing seconds, bytes)."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Writer

    with open(log, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        wanted = {cid for cid, c in summary.channels.items() if c.message_encoding == "cdr"}
        messages = [
            (ch.id, m.log_time, m.data) for _, ch, m in reader.iter_messages(log_time_order=True) if ch.id in wanted
        ]
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    for schema in summary.schemas.values():  # the log's ros2msg definitions (a type, then its dependencies)
        if schema.encoding == "ros2msg":
            for i, part in enumerate(schema.data.decode().split("=" * 80 + "\n")):
                if i == 0:
                    store.register(get_types_from_msg(part, schema.name))
                else:
                    head, text = part.split("\n", 1)
                    store.register(get_types_from_msg(text, head.removeprefix("MSG: ").replace("/", "/msg/", 1)))
    t0 = time.perf_counter()
    with Writer(bag, version=9) as writer:
        connections = {}
        for cid in sorted(wanted):
            channel = summary.channels[cid]
            key = (channel.topic, summary.schemas[channel.schema_id].name)
            if key not in connections:
                connections[key] = writer.add_connection(key[0], key[1], typestore=store)
        by_id = {}
        for cid in wanted:
            channel = summary.channels[cid]
            by_id[cid] = connections[(channel.topic, summary.schemas[channel.schema_id].name)]
        for cid, log_time, data in messages:
            writer.write(by_id[cid], log_time, data)
    wall = time.perf_counter() - t0
    size = sum(p.stat().st_size for p in bag.rglob("*") if p.is_file())
    return len(messages), wall, size


def rewrite_cost(log: Path, again: Path) -> tuple[float, float]:
    """CPU seconds (writing thread, whole process) to write ``log``'s messages (read beforehand) into a new
    McapLogger with the compression ``cufund run`` uses: the log's own cost without the simulation around it."""
    import inspect

    from cufund.scenarios import run_folder

    compression = "zstd" if 'compression="zstd"' in inspect.getsource(run_folder.run_into_folder) else "lz4"
    records = list(read_mcap(log))
    gc.collect()
    t0, p0 = time.thread_time(), time.process_time()
    with McapLogger(again, compression=compression) as out:
        write = out.write
        for r in records:
            write(r.topic, r.message, r.log_time_ns, r.publish_time_ns)
    return time.thread_time() - t0, time.process_time() - p0


def bench_runs(tmp: Path, repeats: int, scenarios: list[str], bag: bool) -> None:
    import cufund
    from cufund.scenarios.run_folder import run_into_folder

    print(f"4. run logs ({cufund.__file__}): {repeats} alternating runs with and without the log, medians")
    for name in scenarios:
        config = cufund.load_scenario(name)
        walls: dict[str, list[float]] = {"without": [], "with": []}
        cpus: dict[str, list[float]] = {"without": [], "with": []}
        for k in range(repeats):
            for kind in ("without", "with"):
                gc.collect()
                out = tmp / f"{name}_{kind}_{k}"
                t0, p0 = time.perf_counter(), time.process_time()
                run_into_folder(config, out, log=kind == "with", plots=False, replay=False)
                walls[kind].append(time.perf_counter() - t0)
                cpus[kind].append(time.process_time() - p0)
        log = tmp / f"{name}_with_0" / "run.mcap"
        wall_without, wall_with = statistics.median(walls["without"]), statistics.median(walls["with"])
        cpu_without, cpu_with = statistics.median(cpus["without"]), statistics.median(cpus["with"])
        print(
            f"   {name}: run.mcap {log.stat().st_size / 1e6:.1f} MB; wall {wall_without:.2f} s without, "
            f"{wall_with:.2f} s with the log ({(wall_with / wall_without - 1) * 100:+.1f} %); process CPU "
            f"{cpu_without:.2f} s without, {cpu_with:.2f} s with ({(cpu_with - cpu_without) / wall_without * 100:+.1f} % "
            f"of the run's wall time); load average {os.getloadavg()[0]:.2f}"
        )
        main, process = rewrite_cost(log, tmp / f"{name}_again.mcap")
        print(
            f"   {name}: its messages written again into a McapLogger as the run did (load-independent): "
            f"{process:.2f} s of CPU, {main:.2f} s of it on the writing thread"
        )
        if bag:
            n, seconds, size = write_rosbag(log, tmp / f"{name}_bag")
            print(
                f"   {name}: the same {n} ROS 2 messages (the log's CDR channels) as a rosbags ROS 2 bag "
                f"(sqlite3, uncompressed): {size / 1e6:.1f} MB, written in {seconds:.2f} s"
            )
        for k in range(repeats):
            for kind in ("without", "with"):
                for f in (tmp / f"{name}_{kind}_{k}").glob("*"):
                    f.unlink()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="alternating square runs with and without the log")
    parser.add_argument("--square-only", action="store_true", help="only part 2 (the square with and without)")
    parser.add_argument("--once", choices=("with", "without"), help="one square run (for callgrind), nothing else")
    parser.add_argument("--runs", action="store_true", help="only part 4: the run logs of square and tunnel")
    parser.add_argument("--run-repeats", type=int, default=3, help="alternating runs per scenario in part 4")
    parser.add_argument("--scenarios", nargs="+", default=["square", "tunnel"], help="part 4's scenarios")
    parser.add_argument("--tree", help="part 4 on this cufund source tree (the folder holding cufund/)")
    parser.add_argument("--no-bag", action="store_true", help="part 4 without the rosbags bag")
    args = parser.parse_args()
    if args.once:
        square_once(args.once)
        return
    if args.runs or args.tree:
        with tempfile.TemporaryDirectory() as tmp:
            bench_runs(Path(tmp), args.run_repeats, args.scenarios, bag=not args.no_bag and not args.tree)
        return
    with tempfile.TemporaryDirectory() as tmp:
        if not args.square_only:
            bench_types(Path(tmp))
        path = bench_square(Path(tmp), args.repeats)
        if path is not None and not args.square_only:
            bench_read(path)


if __name__ == "__main__":
    main()
