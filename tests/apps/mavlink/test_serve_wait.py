"""set_link_loss_timeout: COM_DL_LOSS_T through each run's commander, the first refusal named."""

from __future__ import annotations

from concurrent.futures import Future

from cufund.apps.live import LiveRun
from cufund.apps.mavlink.serve_wait import set_link_loss_timeout
from cufund.missions.commands import CommandAck


class _Run:
    def __init__(self, result: str, message: str = "") -> None:
        self.result, self.message = result, message
        self.seen: list[dict] = []

    def submit(self, cmd: dict) -> Future:
        self.seen.append(cmd)
        fut: Future = Future()
        fut.set_result(CommandAck(cmd["command"], self.result, self.message))
        return fut


def test_every_run_takes_it_or_the_first_refusal_is_named() -> None:
    a, b = _Run("accepted"), _Run("accepted")
    assert set_link_loss_timeout({"uav1": a, "uav2": b}, 3) == ""
    assert a.seen == b.seen == [{"command": "set_param", "name": "COM_DL_LOSS_T", "value": 3.0}]
    c = _Run("denied", "COM_DL_LOSS_T must be in [0, 60] s")
    assert set_link_loss_timeout({"uav1": a, "uav2": c}, 99) == (
        "--link-loss-timeout (uav2): COM_DL_LOSS_T must be in [0, 60] s"
    )
    assert set_link_loss_timeout({"": c}, 99) == "--link-loss-timeout: COM_DL_LOSS_T must be in [0, 60] s"


def test_a_real_commander_takes_a_valid_timeout() -> None:
    run = LiveRun("vehicle", start=False)
    try:
        run.start()
        assert set_link_loss_timeout({"": run}, 2.5) == ""
        values = run.submit({"command": "get_params"}).result(timeout=10).data
        assert values["COM_DL_LOSS_T"] == 2.5
        assert set_link_loss_timeout({"": run}, -1).startswith("--link-loss-timeout: ")  # refused, with the reason
    finally:
        run.stop()
