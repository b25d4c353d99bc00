"""Sweep files without a cluster: expansion, draws, keys, validation, and the report's confidence intervals."""

import math

import numpy as np
import pytest
from scipy import stats

import cufund
from cufund.apps.sweep import config_key, load_spec
from cufund.apps.sweep.report import t_interval, wilson_interval
from cufund.scenarios import load_scenario


def test_grid_times_draws_times_repeats_resolve_like_load_scenario():
    spec = load_spec(
        {
            "scenario": "square",
            "set": {"duration": 3},
            "grid": {"controller.kind": ["pid", "geometric"], "seed": [3, 8]},
            "random": {
                "n": 3,
                "seed": 5,
                "draws": {"controller.position.xy_p": {"uniform": [0.8, 1.2]}, "trajectory.hover_s": {"range": [1, 4]}},
            },
            "repeats": 2,
        }
    )
    variants = spec.variants()
    assert len(variants) == 2 * 2 * 3 * 2
    assert spec.swept_keys == ["controller.kind", "seed", "controller.position.xy_p", "trajectory.hover_s"]
    rng = np.random.default_rng(5)  # the draws, in file order, from the sweep's own seed
    expected = [(rng.uniform(0.8, 1.2), int(rng.integers(1, 4))) for _ in range(3)]
    drawn = sorted({(v.overrides["controller.position.xy_p"], v.overrides["trajectory.hover_s"]) for v in variants})
    assert drawn == sorted(expected)
    for v in variants:
        if v.repeat == 0:  # repeat 0 is exactly the scenario with its overrides
            assert v.config == load_scenario("square", {"duration": 3, **v.overrides})
            assert v.key == config_key(v.config)
        else:  # another repeat differs by its seed only
            assert v.config.seed not in (3, 8)
            assert v.config.replace(seed=v.overrides["seed"]) == load_scenario("square", {"duration": 3, **v.overrides})
    assert len({v.key for v in variants}) == len(variants)


def test_key_is_the_resolved_configuration():
    a = load_scenario("square", {"seed": 3})
    assert config_key(a) == config_key(load_scenario("square", ["seed=3"]))
    assert config_key(a) == config_key(a.with_overrides({"controller.kind": "pid"}))  # the same run, spelled twice
    assert config_key(a) != config_key(a.with_overrides({"controller.position.xy_p": 3.0001}))


@pytest.mark.parametrize(
    "spec, field",
    [
        ({"scenario": "square", "grid": {"controller.position.xy_pp": [1.0, 2.0]}}, "xy_pp"),
        ({"scenario": "square", "grid": {"controller.position.xy_p": [3.0, "fast"]}}, "xy_p"),
        ({"scenario": "square", "grid": {"controller.kind": ["pid", "lqr"]}}, "lqr"),
        ({"scenario": "square", "random": {"n": 2, "draws": {"seed": {"uniform": [2, 1]}}}}, "sweep.random.draws.seed"),
        ({"scenario": "square", "random": {"n": 2, "draws": {"seed": {"gauss": [0, 1]}}}}, "sweep.random.draws.seed"),
        ({"scenario": "square", "grid": {"seed": []}}, "sweep.grid.seed"),
        ({"scenario": "square", "repeats": 0}, "sweep.repeats"),
        ({"scenario": "square", "grids": {}}, "grids"),
        ({"scenario": "no_such_scenario"}, "no_such_scenario"),
    ],
)
def test_a_bad_sweep_names_the_field(spec, field):
    with pytest.raises(cufund.ConfigError, match=field.replace(".", r"\.")):
        load_spec(spec).variants()


def test_a_bad_override_names_its_variant():
    spec = load_spec({"scenario": "square", "grid": {"seed": [1, 2], "controller.position.xy_p": [3.0, -1.0]}})
    with pytest.raises(cufund.ConfigError, match=r"sweep variant seed=1, controller\.position\.xy_p=-1\.0: "):
        spec.variants()


def test_wilson_interval_matches_scipy():
    for k, n in [(0, 5), (3, 7), (10, 10), (41, 100)]:
        ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert wilson_interval(k, n) == pytest.approx((ci.low, ci.high), abs=1e-6)
    assert all(math.isnan(x) for x in wilson_interval(0, 0))


def test_t_interval_matches_scipy():
    v = np.array([1.0, 2.5, 2.0, np.nan, 4.0])
    finite = v[np.isfinite(v)]
    lo, hi = stats.t.interval(0.95, finite.size - 1, loc=finite.mean(), scale=stats.sem(finite))
    assert t_interval(v) == pytest.approx((finite.mean(), lo, hi), rel=1e-12)


def test_report_bins_drawn_values_and_writes_mixed_columns(tmp_path):
    import pandas as pd

    from cufund.apps.sweep.report import groups, write_outputs
    from cufund.apps.sweep.results import results_frame
    from cufund.apps.sweep.spec import Variant

    rng = np.random.default_rng(0)
    spec = load_spec(
        {
            "scenario": "square",
            "grid": {"world.kind": ["empty", 3]},  # a mixed column (text, int)
            "random": {"n": 20, "draws": {"controller.position.xy_p": {"uniform": [2.0, 4.0]}}},
        }
    )
    variants, records = [], {}
    for i in range(40):
        key = f"{i:016x}"
        overrides = {"world.kind": ["empty", 3][i % 2], "controller.position.xy_p": float(rng.uniform(2, 4))}
        variants.append(Variant(i, overrides, 0, None, key))
        ok = overrides["controller.position.xy_p"] > 3
        records[key] = {
            "key": key,
            "status": "completed" if ok else "crashed",
            "message": "",
            "attempts": 1,
            "variant_wall_s": 1.0,
            "metrics": {"tracking_rmse_m": None if not ok else i * 1e-3, "tracking_window_s": [3.4, 12.0]},
        }
    frame = results_frame(variants, records, spec.swept_keys, 1, tmp_path)
    parts = groups(frame, "controller.position.xy_p")
    assert len(parts) == 8 and sum(len(rows) for _, _, rows in parts) == 40
    xs = [x for _, x, _ in parts]
    assert xs == sorted(xs)
    write_outputs(tmp_path, spec, frame, 40)
    back = pd.read_parquet(tmp_path / "results.parquet")
    assert back["world.kind"].tolist() == ["empty", "3"] * 20 and back["tracking_window_s.1"].tolist() == [12.0] * 40
    assert back["tracking_rmse_m"].isna().sum() == (back["status"] != "completed").sum()
    summary = (tmp_path / "summary.md").read_text()
    assert "40 of 40 variants" in summary and "## `controller.position.xy_p`" in summary
    empty = frame[frame["world.kind"] == "empty"]
    k = int((empty["status"] == "completed").sum())
    lo, hi = wilson_interval(k, 20)
    assert f"| empty | 20 | {k / 20:.0%} [{lo:.0%}, {hi:.0%}] |" in summary
    assert {p.name for p in (tmp_path / "plots").iterdir()} == {"world.kind.png", "controller.position.xy_p.png"}
