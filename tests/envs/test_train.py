"""cufund train: a short seeded PPO run on Hover-v0 beats random actions by a set margin; the exported ONNX policy
gives the library's actions on 100 observations; the manifest says what the policy is; bad input names the field."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("skrl")
pytest.importorskip("onnxruntime")

from cufund.apps.cli import main
from cufund.control.policy_manifest import OBS_LAYOUT_VERSION, PolicyManifest
from cufund.core.config import ConfigError
from cufund.envs.train import (
    TrainConfig,
    evaluate_policy,
    library_actions,
    linear_lr,
    make_env,
    onnx_actor,
    train,
)

# PPO on Hover-v0 (collective thrust + body rates through the rate loop) for a budget that fits CI: about 50 s of
# training on 2 cores, JAX's compilation included, 1.5 M steps. The margin is the least improvement of the mean
# first-episode return (100 envs, a seed training never saw) over uniformly random actions: measured 2.2 -> 55.3
# (the most a 5 s episode can give is 500; zero actions give 0.0)
HOVER = TrainConfig(
    task="Hover", steps=1_500_000, num_envs=256, seed=0, init_log_std=-1.0, env_kwargs={"action_mode": "thrust_rates"}
)
MARGIN = 25.0


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("hover")
    result, agent = train(HOVER, out, progress=False, evaluate_envs=100, log=None)
    return result, agent


def test_ppo_on_hover_beats_random_actions_by_the_margin(trained):
    result, _ = trained
    assert np.isfinite(result.mean_return_random) and np.isfinite(result.mean_return)
    assert result.mean_return > result.mean_return_random + MARGIN, (result.mean_return_random, result.mean_return)
    assert result.env_steps >= HOVER.steps


def test_exported_onnx_gives_the_library_actions_on_100_observations(trained):
    result, agent = trained
    env = make_env(HOVER.task_id, 100, HOVER.env_kwargs)
    rng = np.random.default_rng(7)
    obs, _ = env.reset(seed=99)
    for _ in range(15):  # away from the spawn distribution's centre: tilted, spinning, moving
        obs, *_ = env.step(rng.uniform(-1, 1, (100, 4)).astype(np.float32))
    env.close()
    want = library_actions(agent, obs)
    got = onnx_actor(result.onnx_path)(obs)
    assert got.shape == (100, 4) and got.dtype == np.float32
    # float32 arithmetic in another order (XLA vs onnxruntime's GEMM): a few units in the last place of |a| <= 1
    np.testing.assert_allclose(got, want, rtol=0, atol=32 * np.finfo(np.float32).eps)
    assert np.ptp(want, axis=0).min() > 1e-3  # the comparison is not between constants


def test_manifest_and_logs(trained):
    result, _ = trained
    m = PolicyManifest.read(result.out / "policy.yaml")
    assert m == result.manifest
    assert (m.task, m.action_mode, m.rate_hz, m.seed) == ("cufund/Hover-v0", "thrust_rates", 100.0, 0)
    assert m.obs_layout_version == OBS_LAYOUT_VERSION and m.obs_dim == 22 and m.act_dim == 4
    m.check_layout()
    assert list((result.out / "skrl").glob("events.out.tfevents.*")), "skrl's TensorBoard events"
    assert TrainConfig.from_yaml(result.out / "train_config.yaml") == HOVER


def test_random_baseline_is_seeded():
    a = evaluate_policy(None, "cufund/Hover-v0", num_envs=8, seed=3)
    b = evaluate_policy(None, "cufund/Hover-v0", num_envs=8, seed=3)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"algo": "dqn"}, "train.algo"),
        ({"steps": 0}, "train.steps"),
        ({"num_envs": 2.5}, "train.num_envs"),
        ({"seed": -1}, "train.seed"),
        ({"hidden": []}, "train.hidden"),
        ({"learning_rate": float("nan")}, "train.learning_rate"),
        ({"discount_factor": 1.5}, "train.discount_factor"),
        ({"mini_batches": 10_000, "num_envs": 2, "rollouts": 2}, "train.mini_batches"),
        ({"lr_schedule": "cosine"}, "train.lr_schedule"),
        ({"lr_final": 0.0}, "train.lr_final"),
        ({"grad_norm_clip": -1.0}, "train.grad_norm_clip"),
    ],
)
def test_bad_config_names_the_field(kw, field):
    with pytest.raises(ConfigError, match=field):
        TrainConfig(**kw)


def test_task_names_and_unknown_task():
    assert TrainConfig(task="Hover").task_id == "cufund/Hover-v0"
    assert TrainConfig(task="cufund/Waypoints-v0").task_id == "cufund/Waypoints-v0"
    with pytest.raises(ConfigError, match="unknown task 'cufund/Nope-v0'"):
        make_env("cufund/Nope-v0", 2)


def test_cli_refuses_bad_input_with_exit_2(tmp_path, capsys):
    assert main(["train", "Nope", "--out", str(tmp_path / "a"), "--steps", "10"]) == 2
    assert "unknown task" in capsys.readouterr().err
    assert main(["train", "Hover", "--out", str(tmp_path / "b"), "--env", "action_mode"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    assert main(["train", "Hover", "--out", str(tmp_path / "c"), "--env", "action_mode=warp"]) == 2
    assert "action_mode" in capsys.readouterr().err
    (tmp_path / "cfg.yaml").write_text(json.dumps({"task": "Hover", "stepz": 5}))
    assert main(["train", "--config", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "d")]) == 2
    assert "stepz" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["train", "Hover"])  # --out is required


def test_linear_schedule_multiplies_the_rate_along_the_line():
    """skrl's PPO multiplies its learning rate by the schedule's value after every learning epoch of an update (so
    several times at one timestep), one schedule per network: the running product follows 1 - (1 - final) t / total
    and stays at final past the end."""
    total, final = 1000, 0.1
    policy, value = linear_lr(total=total, final=final), linear_lr(total=total, final=final)
    lr_policy = lr_value = 1.0
    for t in range(0, 1200, 32):  # an update every 32 steps, as rollouts=32
        for _ in range(5):  # learning_epochs=5
            lr_policy *= policy(t)
            lr_value *= value(t)
        want = max(final, 1.0 - (1.0 - final) * (t + 1) / total)
        assert lr_policy == pytest.approx(want, rel=1e-12) and lr_value == pytest.approx(want, rel=1e-12)
