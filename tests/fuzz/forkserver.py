"""Runs fuzz cases, each in its own forked process under an address-space cap (the fuzz tests' server).

Started once per test session (``python forkserver.py``); it imports cufund once, then for every request
forks a child that caps its address space (``RLIMIT_AS``), runs the case and reports how it ended.
The server itself never runs a case, so a crash or a hang only ever takes one child down.

Protocol (stdin/stdout, length-prefixed pickles): request ``(setup, call, args, check, timeout_s, cap_bytes)``;
reply ``(outcome, detail, seconds)``. ``args`` values marked as code are evaluated in the child (huge
broadcast arrays, which must not be built in the parent); they cross the pipe as ``("__code__", source)``.
Outcomes:

- ``ok``: the call returned and ``check`` (if any) held — the result is not garbage;
- ``clean``: ValueError / TypeError / ConfigError (or MemoryError) with a message;
- ``generic``: pybind11's "incompatible function arguments" or an empty message (names no argument);
- ``wrong_type``: any other exception type (RecursionError, OverflowError, RuntimeError, IndexError, ...);
- ``garbage``: returned, but ``check`` failed (e.g. NaN in a result);
- ``crash``: the child died of a signal (segfault, abort) or exited without reporting;
- ``hang``: the child ran past ``timeout_s`` (killed).
"""

from __future__ import annotations

import os
import pickle
import resource
import select
import signal
import struct
import sys
import time
import traceback
import warnings


def _read(stream) -> object:
    head = stream.read(8)
    if len(head) < 8:
        raise EOFError
    (n,) = struct.unpack("<Q", head)
    return pickle.loads(stream.read(n))


def _write(stream, obj: object) -> None:
    data = pickle.dumps(obj)
    stream.write(struct.pack("<Q", len(data)) + data)
    stream.flush()


# Messages Python or numpy produce on their own: they name no cufund argument or field.
_INTERNAL = (
    "could not convert",
    "invalid literal",
    "object of type",
    "unsupported operand",
    "not subscriptable",
    "has no len",
    "only integer scalar",
    "setting an array element with a sequence",
    "unhashable",
    "object is not iterable",
    "cannot convert float",
    "must be real number, not",
    "takes no keyword",
    "got an unexpected keyword",
    "missing 1 required",
    "object cannot be interpreted",
    "could not broadcast",
    "truth value of an array",
    "Cannot cast ufunc",
    "ufunc '",
)


def _classify(exc: BaseException) -> tuple[str, str]:
    import cufund

    text = f"{type(exc).__name__}: {exc}"[:300]
    if isinstance(exc, MemoryError):
        return "clean", text
    if isinstance(exc, (ValueError, TypeError, cufund.ConfigError)):
        msg = str(exc).strip()
        if not msg or "incompatible function arguments" in msg or "Unable to cast" in msg:
            return "generic", text
        # A message naming a field and what it must be is clean even when it quotes Python's own words.
        if any(phrase in msg for phrase in _INTERNAL) and " must " not in msg and "invalid YAML" not in msg:
            return "generic", text + " | " + "".join(traceback.format_tb(exc.__traceback__)[-2:])[-300:]
        return "clean", text
    return "wrong_type", text + " | " + "".join(traceback.format_tb(exc.__traceback__)[-2:])[-400:]


def _child(setup: str, call: str, args: dict, check: str | None, cap: int, wfd: int) -> None:
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    outcome: tuple[str, str]
    try:
        import numpy as np

        import cufund

        ns: dict[str, object] = {"np": np, "cufund": cufund}
        exec(setup, ns)
        for k, v in args.items():
            ns[k] = eval(v[1], ns) if isinstance(v, tuple) and len(v) == 2 and v[0] == "__code__" else v
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if "\n" in call or call.startswith("result ="):
                    exec(call, ns)
                else:
                    ns["result"] = eval(call, ns)
        except BaseException as e:
            outcome = _classify(e)
        else:
            if check is None or eval(check, ns):
                outcome = ("ok", "")
            else:
                outcome = ("garbage", repr(ns.get("result"))[:300])
    except BaseException as e:
        outcome = ("setup_error", f"{type(e).__name__}: {e}"[:300])
    os.write(wfd, pickle.dumps(outcome))
    os._exit(0)


def _run(setup: str, call: str, args: dict, check: str | None, timeout: float, cap: int) -> tuple[str, str, float]:
    rfd, wfd = os.pipe()
    start = time.monotonic()
    pid = os.fork()
    if pid == 0:
        os.close(rfd)
        try:
            _child(setup, call, args, check, cap, wfd)
        finally:
            os._exit(70)
    os.close(wfd)
    chunks: list[bytes] = []
    deadline = start + timeout
    hung = False
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            hung = True
            break
        ready, _, _ = select.select([rfd], [], [], left)
        if ready:
            data = os.read(rfd, 1 << 16)
            if not data:
                break
            chunks.append(data)
    os.close(rfd)
    if hung:
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    seconds = time.monotonic() - start
    if hung:
        return "hang", f"killed after {timeout} s", seconds
    if os.WIFSIGNALED(status):
        return "crash", f"signal {os.WTERMSIG(status)} ({signal.Signals(os.WTERMSIG(status)).name})", seconds
    try:
        outcome, detail = pickle.loads(b"".join(chunks))
    except Exception:
        return "crash", f"exit status {os.waitstatus_to_exitcode(status)} without a report", seconds
    return outcome, detail, seconds


def main() -> None:
    warnings.simplefilter("ignore")
    import cufund  # noqa: F401 - imported once; every child inherits it

    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    while True:
        try:
            request = _read(stdin)
        except EOFError:
            return
        _write(stdout, _run(*request))


if __name__ == "__main__":
    main()
