"""planning.sequence.Hold's turn (yaw_end): its input checks name what is wrong (the turn itself is tested with the
search's use of it, tests/missions/test_search.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cufund.planning.sequence import Hold


@pytest.mark.parametrize(
    "kw", [{"yaw_end": math.inf}, {"yaw_end": -math.inf}, {"yaw_end": math.nan}, {"yaw": math.inf, "yaw_end": 0.0}]
)
def test_a_turn_between_headings_that_are_not_finite_is_refused_naming_them(kw: dict[str, float]) -> None:
    with pytest.raises(ValueError, match="yaw and yaw_end must be finite angles"):
        Hold(np.zeros(3), 1.0, **kw)
    with pytest.raises(ValueError, match="yaw and yaw_end must be finite angles"):
        Hold.turn(np.zeros(3), kw.get("yaw", 0.0), kw["yaw_end"], 0.8)


def test_a_turn_without_time_is_refused_naming_the_duration() -> None:
    with pytest.raises(ValueError, match=r"a turn needs duration > 0 \[s\], got 0.0"):
        Hold(np.zeros(3), 0.0, 0.0, yaw_end=1.0)
    assert Hold(np.zeros(3), 0.0, 1.0, yaw_end=1.0 + 2 * math.pi).delta == pytest.approx(0.0, abs=1e-12)  # no turn
