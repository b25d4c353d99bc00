"""Sweeps on a 2-worker Dask LocalCluster: equal to the serial runs, resumable, validated before any work, every
socket on 127.0.0.1, and a variant whose worker dies retried once then recorded failed."""

import ipaddress
import json
import math
import os
import signal
import subprocess
import sys
import time

import cloudpickle
import pandas as pd
import psutil
import pytest
from distributed.diagnostics.plugin import WorkerPlugin

import cufund
from cufund.apps.sweep import is_wall_metric, local_client, run
from cufund.apps.sweep.results import flatten
from cufund.scenarios import load_scenario
from cufund.scenarios.build import run_scenario

# 3 gains x 2 seeds of the square, cut at 5 s (the min-snap segment starts at 3.4 s: tracking metrics exist).
SPEC = {
    "scenario": "square",
    "set": {"duration": 5},
    "grid": {"controller.position.xy_p": [2.5, 3.0, 3.5], "seed": [3, 8]},
}


_BEFORE: set = set()
"""This process's sockets from before the cluster started (e.g. a DDS participant an earlier test's bridge left open
in the test process): not the sweep's, so not part of its loopback check."""


@pytest.fixture(scope="module")
def client():
    _BEFORE.update((c.fd, c.laddr) for c in psutil.Process().net_connections("inet"))
    with local_client(2) as c:
        yield c


def _sockets(pids):
    out = []
    for pid in pids:
        try:
            out += psutil.Process(pid).net_connections("inet")
        except psutil.NoSuchProcess:
            pass
    return out


def _assert_loopback(conns):
    assert conns, "no sockets found"
    for c in conns:
        assert ipaddress.ip_address(c.laddr.ip).is_loopback and c.laddr.ip == "127.0.0.1", c
        if c.raddr:
            assert c.raddr.ip == "127.0.0.1", c


def _same(a, b):
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return (
        a == b
        or (a is None and isinstance(b, float) and math.isnan(b))
        or (b is None and isinstance(a, float) and math.isnan(a))
    )


def test_dask_sweep_equals_serial_runs_and_stays_on_loopback(client):
    frame = run(SPEC, client)
    assert len(frame) == 6 and set(frame["status"]) == {"timeout"}
    assert sorted(zip(frame["controller.position.xy_p"], frame["seed"], strict=True)) == sorted(
        (g, s) for g in (2.5, 3.0, 3.5) for s in (3, 8)
    )
    compared = 0
    for _, row in frame.iterrows():
        overrides = {
            "duration": 5,
            "controller.position.xy_p": row["controller.position.xy_p"],
            "seed": int(row["seed"]),
        }
        serial = run_scenario(load_scenario("square", overrides))
        metrics = flatten({k: v for k, v in serial.metrics.items() if k not in ("status", "message")})
        assert row["status"] == serial.result.status.value and row["message"] == serial.result.message
        for name, value in metrics.items():
            if is_wall_metric(name):
                continue
            assert _same(row[name], value), (name, row[name], value)
            compared += 1
    assert compared >= 6 * 5
    assert frame["tracking_rmse_m"].nunique() == 3  # the gain changes the flight (and the comparison means something)
    # every address of the cluster, and every socket of the scheduler (this process) and the worker processes
    info = client.scheduler_info()
    assert info["address"].startswith("tcp://127.0.0.1:")
    assert len(info["workers"]) == 2 and all(a.startswith("tcp://127.0.0.1:") for a in info["workers"])
    pids = [os.getpid(), *client.run(os.getpid).values(), *client.run(os.getpid, nanny=True).values()]
    assert len(set(pids)) >= 3
    _assert_loopback([c for c in _sockets(set(pids)) if (c.fd, c.laddr) not in _BEFORE])
    assert set(client.run(lambda: os.environ.get("CUFUND_NUM_THREADS")).values()) == {"1"}
    assert set(client.run(lambda: signal.getsignal(signal.SIGINT)).values()) == {signal.SIG_IGN}


class _NoClient:
    def __getattr__(self, name):
        raise AssertionError(f"the sweep used its client ({name}) before validating every variant")


def test_a_bad_override_fails_before_any_variant_runs(tmp_path):
    bad = {**SPEC, "grid": {**SPEC["grid"], "controller.position.xy_pp": [1.0]}}
    with pytest.raises(cufund.ConfigError, match=r"xy_pp"):
        run(bad, _NoClient(), out=tmp_path / "sw")
    assert not (tmp_path / "sw").exists()
    (tmp_path / "bad.yaml").write_text("scenario: square\ngrid:\n  controller.position.xy_p: [3.0, fast]\n")
    cli = subprocess.run(
        [sys.executable, "-m", "cufund.apps.cli", "sweep", str(tmp_path / "bad.yaml"), "--out", str(tmp_path / "sw")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert cli.returncode == 2
    assert cli.stderr.count("\n") == 1 and "controller.position.xy_p" in cli.stderr and "fast" in cli.stderr
    assert not (tmp_path / "sw").exists()


def test_killed_sweep_resumes_only_unfinished_variants(client, tmp_path):
    spec_file = tmp_path / "sweep.yaml"
    spec_file.write_text(json.dumps(SPEC))  # JSON is YAML
    out = tmp_path / "sw"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cufund.apps.cli",
            "sweep",
            str(spec_file),
            "--out",
            str(out),
            "--workers",
            "2",
            "--no-plots",
        ],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    conns = []
    try:
        deadline = time.monotonic() + 240
        while not list(out.glob("variants/*/result.json")):
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "no variant finished"
            tree = [proc.pid] + [c.pid for c in psutil.Process(proc.pid).children(recursive=True)]
            conns += _sockets(tree)
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the CLI, its scheduler and its workers, mid-sweep
        proc.wait()
        proc.stderr.close()
    _assert_loopback(conns)  # the CLI's own local cluster, sampled while it ran
    before = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("variants/*/result.json")}
    assert 1 <= len(before) < 6
    frame = run(spec_file, client, out=out, plots=False)
    assert sorted(frame.attrs["reused"]) == sorted(before)
    assert len(frame.attrs["ran"]) == 6 - len(before) and not set(frame.attrs["ran"]) & set(before)
    assert len(frame) == 6 and set(frame["status"]) == {"timeout"}
    assert {k: (out / "variants" / k / "result.json").stat().st_mtime_ns for k in before} == before
    assert (pd.read_parquet(out / "results.parquet")["key"].tolist()) == frame["key"].tolist()
    again = run(spec_file, client, out=out, plots=False)  # nothing left to do
    assert again.attrs["ran"] == [] and len(again.attrs["reused"]) == 6


class _CrashingKind(WorkerPlugin):
    """A Dask worker plugin: in each worker (restarted ones included) the controller kind ``sweep_crash`` kills
    its process when built."""

    def setup(self, worker):
        import os

        from cufund.control.kinds import ControllerParams
        from cufund.core import registry

        def crash(params, ctx):
            os._exit(17)

        registry.register(registry.Kind("controller", "sweep_crash", ControllerParams, crash), replace=True)


def test_a_variant_whose_worker_dies_is_retried_once_then_failed(client, tmp_path):
    from cufund.core import registry

    pid = registry.lookup("controller", "pid")  # in this process the kind builds (validation passes)
    registry.register(registry.Kind("controller", "sweep_crash", pid.params, pid.build, pid.defaults), replace=True)
    try:
        cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this test file
        try:
            client.register_plugin(_CrashingKind(), name="cufund-test-crash")
        finally:
            cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
        spec = {"scenario": "square", "set": {"duration": 1}, "grid": {"controller.kind": ["sweep_crash", "pid"]}}
        frame = run(spec, client, out=tmp_path / "sw", plots=False).set_index("controller.kind")
    finally:
        registry.unregister("controller", "sweep_crash")
        client.unregister_worker_plugin("cufund-test-crash")
    # the good variant still completes; it takes a second attempt when the crash's retry lands on its worker and
    # kills it mid-run (which of the two workers runs what is Dask's choice)
    assert frame.loc["pid", "status"] == "timeout" and frame.loc["pid", "attempts"] in (1, 2)
    assert frame.loc["sweep_crash", "status"] == "failed" and frame.loc["sweep_crash", "attempts"] == 2
    assert "worker died twice" in frame.loc["sweep_crash", "message"]
    summary = (tmp_path / "sw" / "summary.md").read_text()
    assert "## Failed variants" in summary and "worker died twice" in summary
    client.wait_for_workers(2, timeout=60)  # the nanny restarted them


def test_a_sweep_on_a_scheduler_by_address(client):
    def clients(dask_scheduler):
        return sorted(dask_scheduler.clients)

    before = client.run_on_scheduler(clients)
    spec = {"scenario": "square", "set": {"duration": 1}, "grid": {"controller.kind": ["pid", "geometric"]}}
    frame = run(spec, scheduler=client.scheduler.address)
    assert frame["controller.kind"].tolist() == ["pid", "geometric"] and set(frame["sim_time_s"]) == {1.0}
    assert set(frame["attempts"]) == {1}
    assert client.run_on_scheduler(clients) == before  # its own client came and went


def test_ctrl_c_stops_cleanly_and_keeps_what_finished(tmp_path):
    spec_file = tmp_path / "sweep.yaml"
    spec_file.write_text(json.dumps(SPEC))
    out = tmp_path / "sw"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cufund.apps.cli",
            "sweep",
            str(spec_file),
            "--out",
            str(out),
            "--workers",
            "2",
            "--no-plots",
        ],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 240
        while not list(out.glob("variants/*/result.json")):
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)  # what a terminal's Ctrl-C sends: the CLI and its workers
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 1 and "interrupted" in err and "Traceback" not in err
    finished = sorted(p.parent.name for p in out.glob("variants/*/result.json"))
    assert 1 <= len(finished) < 6
    assert sorted(pd.read_parquet(out / "results.parquet")["key"]) == finished
    assert f"{len(finished)} of 6 variants have a result" in (out / "summary.md").read_text()
