"""The shared C++ thread pool seen from Python: its size, and fork safety (issues 10 and 11)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest


def _run(code: str, env: dict[str, str] | None = None, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-W", "ignore", "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, **(env or {})},
    )


@pytest.mark.parametrize("n", ["1", "3"])
def test_pool_size_follows_cufund_num_threads(n):
    r = _run("from cufund import _core; print(_core.thread_pool_size())", {"CUFUND_NUM_THREADS": n})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == n


def test_pool_size_defaults_to_the_cpus_this_process_may_use():
    # Pinned to one CPU (taskset's job, done here with sched_setaffinity before the pool exists).
    code = """
        import os
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        from cufund import _core
        print(_core.thread_pool_size(), len(os.sched_getaffinity(0)))
    """
    env = {k: v for k, v in os.environ.items() if k != "CUFUND_NUM_THREADS"}
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=60, env=env
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["1", "1"]


def test_bad_cufund_num_threads_is_a_clear_error():
    r = _run(
        """
        import numpy as np, cufund
        b = cufund.QuadrotorBatch(cufund.vehicle.presets.crazyflie(), 1000)
        try:
            b.step(1e-3, np.zeros((1000, 4)))
        except ValueError as e:
            print("ValueError:", e)
    """,
        {"CUFUND_NUM_THREADS": "many"},
    )
    assert r.returncode == 0, r.stderr
    assert "CUFUND_NUM_THREADS must be an integer in [1, 1024], got 'many'" in r.stdout


def test_fork_while_another_thread_steps_a_large_batch_gives_a_working_child():
    # Without the pool's fork handlers the child inherits a lock held by a thread that does not exist
    # there, and its first parallel loop hangs (9 forks of 10 in the measurement).
    r = _run(
        """
        import os, threading, time
        import numpy as np, cufund
        params = cufund.vehicle.presets.crazyflie()
        big = cufund.QuadrotorBatch(params, 100_000)
        cmd = np.full((100_000, 4), params.hover_rotor_speed)
        stop = False
        def spin():
            while not stop:
                big.step(1e-3, cmd)
        t = threading.Thread(target=spin)
        t.start()
        time.sleep(0.2)
        hung = 0
        for _ in range(8):
            pid = os.fork()
            if pid == 0:
                big.step(1e-3, cmd)  # the same object and the pool, in the child
                small = cufund.QuadrotorBatch(params, 5000)
                small.step(1e-3, np.zeros((5000, 4)))
                os._exit(0 if np.isfinite(big.p).all() else 3)
            for _ in range(1000):
                done, status = os.waitpid(pid, os.WNOHANG)
                if done:
                    break
                time.sleep(0.01)
            else:
                os.kill(pid, 9)
                os.waitpid(pid, 0)
                hung += 1
                continue
            assert os.waitstatus_to_exitcode(status) == 0, status
            time.sleep(0.02)
        stop = True
        t.join()
        print("hung", hung)
    """,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "hung 0"


@pytest.mark.skipif(os.environ.get("CUFUND_EXPECT_SANITIZED") != "1", reason="only under `make sanitize`")
def test_the_sanitised_extension_is_the_one_under_test():
    from cufund import _core

    assert "sanitize-py" in _core.__file__
