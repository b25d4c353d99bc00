"""The geometric controller's integral term takes up a plant that is not the controller's model."""

import pytest

from cufund.control.geometric_controller import GeometricControlParams
from cufund.core.config import ConfigError
from cufund.scenarios import load_scenario
from cufund.scenarios.build import run_scenario

_OFF_MODEL = {"profile": "ideal", "vehicle": {"mass_pct": 5.0, "thrust_constant_pct": 5.0}}


def _square(k_i: float) -> dict:
    cfg = load_scenario(
        "square", {"realism": _OFF_MODEL, "controller": {"kind": "geometric", "geometric": {"k_i": k_i}}}
    )
    return run_scenario(cfg).metrics


def test_the_integral_term_removes_the_offset_a_mismatched_plant_leaves():
    without, with_i = _square(0.0), _square(2.0)
    scale = without["realism"]["mass_scale"] / without["realism"]["thrust_constant_scale"]
    assert abs(scale - 1.0) > 0.02  # this seed's plant is a few percent off the model
    # Lee's law without it: a steady offset of about g (scale - 1) / k_x, here centimetres
    assert without["tracking_rmse_m"] > 0.5 * 9.81 * abs(scale - 1.0) / 6.0
    assert with_i["status"] == "completed" and with_i["tracking_rmse_m"] < 0.5 * without["tracking_rmse_m"]


def test_integral_gains_are_checked():
    with pytest.raises(ConfigError, match="k_i must be below"):
        GeometricControlParams(k_i=30.0)
    with pytest.raises(ConfigError, match="i_band"):
        GeometricControlParams(k_i=1.0, i_band=0.0)
