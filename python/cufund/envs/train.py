"""Training a policy on a cufund task with PPO: ``cufund train TASK --algo ppo --steps N --out DIR``.

The RL library is `skrl <https://skrl.readthedocs.io>`_ (JAX backend, the ``train`` extra): a maintained library
whose JAX agents need no torch. sbx-rl (Stable-Baselines3 in JAX) was the first candidate, but it imports
Stable-Baselines3, which requires torch; from PyPI torch comes with its CUDA stack (several GB) on x86-64 Linux.
skrl[jax] brings jax, flax and optax (about 150 MB, CPU only), takes a Gymnasium ``VectorEnv`` as it is (cufund's
own batched env, no sync wrapper), writes TensorBoard logs of its own and draws a tqdm progress bar.

What :func:`train` writes to ``out``:

- ``policy.onnx``: the deterministic policy (observation standardisation, the MLP, the clip to the action space),
  input ``obs`` [N, obs_dim] float32, output ``action`` [N, act_dim] float32 (:mod:`cufund.envs.export_onnx`);
- ``policy.yaml``: what a deployment checks (:class:`PolicyManifest`: task, action mode, observation layout and its
  version, the policy's rate, the seed, the sizes);
- ``train_config.yaml``: the :class:`TrainConfig` the run used (``cufund train --config`` reads it back);
- ``skrl/``: skrl's TensorBoard event files (rewards, episode lengths, losses, the policy's standard deviation):
  ``tensorboard --logdir DIR/skrl``.

One ``seed`` derives every stream: the env's (``reset(seed=...)``), skrl's JAX key and numpy's.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cufund.control.policy_manifest import PolicyManifest
from cufund.core.config import ConfigError

__all__ = [
    "TrainConfig",
    "TrainResult",
    "evaluate_policy",
    "library_actions",
    "make_env",
    "onnx_actor",
    "policy_layers",
    "train",
]

ALGOS = ("ppo",)
LR_SCHEDULES = ("constant", "linear", "kl_adaptive")


@dataclass(frozen=True)
class TrainConfig:
    """One training run (YAML keys of ``cufund train --config``; the command line's options override them)."""

    task: str = "cufund/Hover-v0"
    """Registered Gymnasium id (``cufund/Hover-v0``) or its short name (``Hover``, ``Hover-v0``)."""
    algo: str = "ppo"
    """RL algorithm (``ppo``)."""
    steps: int = 1_000_000
    """Total environment steps (over all envs)."""
    num_envs: int = 256
    """Vehicles simulated side by side."""
    seed: int = 0
    """Seeds the env's streams, skrl's JAX key and the network initialisation."""
    env_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Keyword arguments of ``gymnasium.make_vec`` (e.g. ``action_mode: thrust_rates``)."""
    hidden: tuple[int, ...] = (64, 64)
    """Hidden layer sizes of the policy and value MLPs (tanh)."""
    rollouts: int = 32
    """Steps per env between PPO updates."""
    learning_epochs: int = 5
    mini_batches: int = 4
    learning_rate: float = 3e-4
    discount_factor: float = 0.99
    gae_lambda: float = 0.95
    entropy_loss_scale: float = 0.0
    ratio_clip: float = 0.2
    value_loss_scale: float = 1.0
    init_log_std: float = -0.5
    """Initial log standard deviation of the Gaussian policy (per action, in the action's units)."""
    grad_norm_clip: float = 0.5
    """Gradients are clipped to this global norm (0: not clipped)."""
    lr_schedule: str = "constant"
    """``constant``; ``linear``: from ``learning_rate`` down to ``learning_rate * lr_final`` at the last step (a
    late update cannot undo what was learned: at a fixed rate, long runs rose, then fell and diverged); or
    ``kl_adaptive``: skrl's KLAdaptiveLR, the learning rate divided by 1.5 when an update's KL divergence exceeds
    2 ``kl_threshold`` and multiplied by 1.5 below half of it (within [1e-6, 1e-2])."""
    lr_final: float = 0.1
    """``linear``: the last learning rate as a fraction of ``learning_rate``."""
    kl_threshold: float = 0.008
    """``kl_adaptive``: the KL divergence the learning rate is steered to."""

    def __post_init__(self) -> None:
        if not isinstance(self.task, str) or not self.task:
            raise ConfigError(f"train.task must be a task name such as 'cufund/Hover-v0', got {self.task!r}")
        if self.algo not in ALGOS:
            raise ConfigError(f"train.algo must be one of {list(ALGOS)}, got {self.algo!r}")
        for name in ("steps", "num_envs", "rollouts", "learning_epochs", "mini_batches"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(f"train.{name} must be an integer >= 1, got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**31:
            raise ConfigError(f"train.seed must be an integer in [0, 2^31), got {self.seed!r}")
        if not isinstance(self.env_kwargs, dict):
            raise ConfigError(f"train.env_kwargs must be a mapping, got {self.env_kwargs!r}")
        hidden = tuple(self.hidden) if isinstance(self.hidden, (list, tuple)) else self.hidden
        if (
            not isinstance(hidden, tuple)
            or not hidden
            or any(isinstance(h, bool) or not isinstance(h, int) or h < 1 for h in hidden)
        ):
            raise ConfigError(f"train.hidden must be a non-empty list of layer sizes >= 1, got {self.hidden!r}")
        object.__setattr__(self, "hidden", hidden)
        for name in (
            "learning_rate",
            "discount_factor",
            "gae_lambda",
            "entropy_loss_scale",
            "ratio_clip",
            "value_loss_scale",
            "init_log_std",
            "grad_norm_clip",
            "kl_threshold",
            "lr_final",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"train.{name} must be a finite number, got {v!r}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ConfigError(f"train.lr_schedule must be one of {list(LR_SCHEDULES)}, got {self.lr_schedule!r}")
        if not 0 < self.lr_final <= 1:
            raise ConfigError(f"train.lr_final must be in (0, 1], got {self.lr_final!r}")
        if self.grad_norm_clip < 0 or self.kl_threshold <= 0:
            raise ConfigError(
                f"train.grad_norm_clip must be >= 0 and train.kl_threshold > 0, got {self.grad_norm_clip!r}, "
                f"{self.kl_threshold!r}"
            )
        if not 0 < self.learning_rate < 1:
            raise ConfigError(f"train.learning_rate must be in (0, 1), got {self.learning_rate!r}")
        if not 0 <= self.discount_factor <= 1 or not 0 <= self.gae_lambda <= 1:
            raise ConfigError(
                f"train.discount_factor and train.gae_lambda must be in [0, 1], got "
                f"{self.discount_factor!r}, {self.gae_lambda!r}"
            )
        if self.rollouts * self.num_envs < self.mini_batches:
            raise ConfigError(
                f"train.mini_batches ({self.mini_batches}) must not exceed rollouts * num_envs "
                f"({self.rollouts * self.num_envs})"
            )

    @property
    def task_id(self) -> str:
        """The Gymnasium id (``cufund/`` and ``-v0`` added to a short name)."""
        t = self.task
        if "/" not in t:
            t = f"cufund/{t}"
        if "-v" not in t.rsplit("/", 1)[1]:
            t = f"{t}-v0"
        return t

    @classmethod
    def from_yaml(cls, path: str | Path, **overrides: Any) -> TrainConfig:
        """Reads a YAML mapping of :class:`TrainConfig` keys; ``overrides`` that are not None win."""
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: a training config is a mapping of TrainConfig keys, got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"{path}: unknown training key(s) {unknown}; known: {sorted(known)}")
        data.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**data)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["hidden"] = list(self.hidden)
        return d


@dataclass(frozen=True)
class TrainResult:
    """What a run produced."""

    out: Path
    onnx_path: Path
    manifest: PolicyManifest
    wall_s: float
    """Wall time of the training loop (env steps and PPO updates, without the evaluations) [s]."""
    env_steps: int
    """Environment steps taken in training (over all envs)."""
    mean_return_random: float
    """Mean first-episode return of uniformly random actions (the evaluation envs, same seed)."""
    mean_return: float
    """Mean first-episode return of the exported policy's deterministic actions (same envs, same seed)."""


def make_env(task_id: str, num_envs: int, env_kwargs: dict[str, Any] | None = None) -> Any:
    """cufund's own batched VectorEnv of a registered task (``import cufund.envs`` registers them)."""
    import gymnasium

    import cufund.envs  # noqa: F401 - registers the tasks

    if task_id not in gymnasium.registry:
        known = sorted(k for k in gymnasium.registry if k.startswith("cufund/"))
        raise ConfigError(f"train.task: unknown task {task_id!r}; registered: {', '.join(known)}")
    try:
        return gymnasium.make_vec(task_id, num_envs=num_envs, **(env_kwargs or {}))
    except TypeError as e:
        raise ConfigError(f"train.env_kwargs: {e}") from None


def evaluate_policy(
    act: Callable[[np.ndarray], np.ndarray] | None,
    task_id: str,
    num_envs: int = 100,
    seed: int = 12345,
    env_kwargs: dict[str, Any] | None = None,
) -> np.ndarray:
    """The return of each of ``num_envs`` envs' first episode (seeded ``seed``) under ``act`` (observations (N, D)
    -> actions (N, 4)); ``act=None`` draws uniformly random actions from a stream seeded ``seed``."""
    env = make_env(task_id, num_envs, env_kwargs)
    rng = np.random.default_rng(seed)
    try:
        obs, _ = env.reset(seed=seed)
        ret = np.zeros(num_envs)
        running = np.ones(num_envs, dtype=bool)
        max_steps = int(getattr(getattr(env, "config", None), "max_steps", 100_000))
        for _ in range(max_steps + 1):
            if act is None:
                a = rng.uniform(-1.0, 1.0, (num_envs, env.single_action_space.shape[0])).astype(np.float32)
            else:
                a = np.asarray(act(np.asarray(obs, dtype=np.float32)), dtype=np.float32)
            obs, r, term, trunc, _ = env.step(a)
            ret += np.where(running, r, 0.0)
            running &= ~(np.asarray(term) | np.asarray(trunc))
            if not running.any():
                break
        return ret
    finally:
        env.close()


def _models(obs_space: Any, act_space: Any, device: Any, hidden: tuple[int, ...], init_log_std: float) -> dict:
    import flax.linen as nn
    import jax.numpy as jnp
    from skrl.models.jax import DeterministicMixin, GaussianMixin, Model

    class Policy(GaussianMixin, Model):
        def __init__(self, **kwargs: Any) -> None:
            Model.__init__(self, **kwargs)
            GaussianMixin.__init__(self, clip_actions=True, clip_log_std=True, min_log_std=-20.0, max_log_std=2.0)

        @nn.compact
        def __call__(self, inputs: dict, role: str = "") -> Any:
            x = inputs["observations"]
            for h in hidden:
                x = nn.tanh(nn.Dense(h)(x))
            mean = nn.Dense(self.num_actions)(x)
            log_std = self.param("log_std", lambda _: init_log_std * jnp.ones(self.num_actions))
            return mean, {"log_std": log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, **kwargs: Any) -> None:
            Model.__init__(self, **kwargs)
            DeterministicMixin.__init__(self, clip_actions=False)

        @nn.compact
        def __call__(self, inputs: dict, role: str = "") -> Any:
            x = inputs["observations"]
            for h in hidden:
                x = nn.tanh(nn.Dense(h)(x))
            return nn.Dense(1)(x), {}

    kw = {"observation_space": obs_space, "action_space": act_space, "device": device}
    models: dict[str, Any] = {"policy": Policy(**kw), "value": Value(**kw)}
    for role, m in models.items():
        m.init_state_dict(role=role)
    return models


def policy_layers(agent: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """The trained policy MLP's layers [(W (in, out), b), ...] in order, as float32 numpy arrays."""
    params = agent.policy.state_dict.params
    params = params.get("params", params)
    names = sorted((k for k in params if k.startswith("Dense_")), key=lambda k: int(k.split("_")[1]))
    return [(np.asarray(params[k]["kernel"], np.float32), np.asarray(params[k]["bias"], np.float32)) for k in names]


def library_actions(agent: Any, obs: np.ndarray) -> np.ndarray:
    """skrl's own deterministic action (its mean action, through its observation preprocessor) clipped to the action
    space as the env clips it: what the exported ONNX policy must reproduce."""
    import jax.numpy as jnp

    x = agent._observation_preprocessor(jnp.asarray(obs, dtype=jnp.float32))
    _, outputs = agent.policy.act({"observations": x}, role="policy")
    return np.clip(np.asarray(outputs["mean_actions"], dtype=np.float32), -1.0, 1.0)


def onnx_actor(onnx_path: str | Path) -> Callable[[np.ndarray], np.ndarray]:
    """An onnxruntime session of an exported policy as a function observations (N, D) -> actions (N, 4)."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    sess = ort.InferenceSession(str(onnx_path), opts, providers=["CPUExecutionProvider"])

    def act(obs: np.ndarray) -> np.ndarray:
        return sess.run(
            ["action"], {"obs": np.asarray(obs, dtype=np.float32).reshape(-1, sess.get_inputs()[0].shape[1])}
        )[0]

    return act


def train(
    cfg: TrainConfig,
    out: str | Path,
    progress: bool = True,
    evaluate_envs: int = 100,
    log: Callable[[str], None] | None = print,
) -> tuple[TrainResult, Any]:
    """Trains ``cfg`` and writes policy.onnx, policy.yaml, train_config.yaml and skrl's TensorBoard logs to ``out``.
    Returns the result and the skrl agent (for comparing the export with the library)."""
    _skrl()
    import jax
    from skrl import config as skrl_config
    from skrl.agents.jax.ppo import PPO, PPO_CFG
    from skrl.envs.wrappers.jax import wrap_env
    from skrl.memories.jax import RandomMemory
    from skrl.resources.preprocessors.jax import RunningStandardScaler
    from skrl.resources.schedulers.jax import KLAdaptiveLR
    from skrl.trainers.jax import SequentialTrainer

    say = log or (lambda _s: None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    task_id = cfg.task_id
    venv = make_env(task_id, cfg.num_envs, cfg.env_kwargs)
    task = getattr(venv, "config", None)
    if task is None:  # pragma: no cover - every cufund task has one
        raise ConfigError(f"train.task: {task_id} is not one of cufund's batched envs (no task config)")
    (out / "train_config.yaml").write_text(yaml.safe_dump(cfg.to_dict(), sort_keys=False), encoding="utf-8")

    skrl_config.jax.backend = "jax"
    skrl_config.jax.key = cfg.seed
    np.random.seed(cfg.seed)
    venv.reset(seed=cfg.seed)  # seeds every env's stream; skrl's own first reset then passes no seed
    env = wrap_env(venv, wrapper="gymnasium", verbose=False)
    env._seed = cfg.seed  # skrl seeds the first reset itself (from its JAX key): use ours
    device = env.device
    models = _models(env.observation_space, env.action_space, device, cfg.hidden, cfg.init_log_std)
    memory = RandomMemory(memory_size=cfg.rollouts, num_envs=env.num_envs, device=device)
    timesteps = -(-cfg.steps // cfg.num_envs)
    scheduler: Any = None
    scheduler_kwargs: Any = {}
    if cfg.lr_schedule == "kl_adaptive":
        scheduler, scheduler_kwargs = KLAdaptiveLR, {"kl_threshold": cfg.kl_threshold}
    elif cfg.lr_schedule == "linear":  # one schedule per network (each keeps its own state)
        scheduler = (linear_lr, linear_lr)
        kw = {"total": timesteps, "final": cfg.lr_final}
        scheduler_kwargs = (kw, dict(kw))
    agent_cfg = PPO_CFG(
        rollouts=cfg.rollouts,
        learning_epochs=cfg.learning_epochs,
        mini_batches=cfg.mini_batches,
        discount_factor=cfg.discount_factor,
        gae_lambda=cfg.gae_lambda,
        learning_rate=cfg.learning_rate,
        ratio_clip=cfg.ratio_clip,
        value_clip=cfg.ratio_clip,
        entropy_loss_scale=cfg.entropy_loss_scale,
        value_loss_scale=cfg.value_loss_scale,
        grad_norm_clip=cfg.grad_norm_clip,
        learning_rate_scheduler=scheduler,
        learning_rate_scheduler_kwargs=scheduler_kwargs,
        time_limit_bootstrap=True,
        observation_preprocessor=RunningStandardScaler,
        observation_preprocessor_kwargs={"size": env.observation_space, "device": device},
        value_preprocessor=RunningStandardScaler,
        value_preprocessor_kwargs={"size": 1, "device": device},
    )
    agent_cfg.experiment.directory = str(out)
    agent_cfg.experiment.experiment_name = "skrl"
    agent_cfg.experiment.checkpoint_interval = 0
    agent = PPO(
        models=models,
        memory=memory,
        observation_space=env.observation_space,
        action_space=env.action_space,
        device=device,
        cfg=agent_cfg,
    )
    trainer = SequentialTrainer(
        env=env,
        agents=agent,
        cfg={
            "timesteps": timesteps,
            "headless": True,
            "disable_progressbar": not progress,
            "close_environment_at_exit": False,
        },
    )
    say(
        f"training {task_id} ({task.action_mode}, {task.control_hz:g} Hz) with skrl PPO (JAX {jax.__version__}): "
        f"{timesteps * cfg.num_envs} steps on {cfg.num_envs} envs, seed {cfg.seed}"
    )
    t0 = time.perf_counter()
    try:
        trainer.train()
    except ValueError as e:
        if "NaN" not in str(e):
            raise
        raise ConfigError(
            f"training diverged after {time.perf_counter() - t0:.0f} s: the policy gave NaN actions ({e}); try a "
            f"smaller train.learning_rate (now {cfg.learning_rate:g}) or fewer train.steps"
        ) from None
    wall = time.perf_counter() - t0
    env_steps = timesteps * cfg.num_envs

    from .export_onnx import export_mlp
    from .vector_env import task_params

    pre = agent._observation_preprocessor
    flown = task_params(task)  # the gains the C++ envs flew the velocity mode with
    manifest = PolicyManifest(
        task=task_id,
        action_mode=task.action_mode,
        rate_hz=float(task.control_hz),
        n_targets=int(task.n_ahead),
        target_dim=int(task.target_dim),
        obs_dim=int(env.observation_space.shape[0]),
        act_dim=int(env.action_space.shape[0]),
        vehicle=str(task.vehicle),
        seed=cfg.seed,
        max_rate=float(task.max_rate),
        max_speed=float(task.max_speed),
        velocity_gain=float(flown.velocity_gain),
        attitude_gain=float(flown.attitude_gain),
        lookahead_s=float(task.lookahead_s),  # 0 unless a timed reference (TaskConfig refuses it otherwise)
        algo=cfg.algo,
        library=f"skrl {_skrl().__version__} (JAX)",
        env_steps=env_steps,
    )
    onnx_path = export_mlp(
        out / "policy.onnx",
        policy_layers(agent),
        manifest,
        obs_mean=np.asarray(pre.running_mean),
        obs_var=np.asarray(pre.running_variance),
        obs_eps=float(pre.epsilon),
        obs_clip=float(pre.clip_threshold),
    )
    mean_random = mean_trained = float("nan")
    if evaluate_envs > 0:
        mean_random = float(np.mean(evaluate_policy(None, task_id, evaluate_envs, cfg.seed + 10_000, cfg.env_kwargs)))
        mean_trained = float(
            np.mean(evaluate_policy(onnx_actor(onnx_path), task_id, evaluate_envs, cfg.seed + 10_000, cfg.env_kwargs))
        )
    result = TrainResult(out, onnx_path, manifest, wall, env_steps, mean_random, mean_trained)
    say(
        f"trained in {wall:.1f} s ({env_steps / max(wall, 1e-9):,.0f} env-steps/s); mean return over "
        f"{evaluate_envs} episodes: random {mean_random:.2f} -> policy {mean_trained:.2f}\n"
        f"wrote {onnx_path} and {onnx_path.with_name('policy.yaml')}; TensorBoard: tensorboard --logdir {out / 'skrl'}"
    )
    venv.close()
    return result, agent


def linear_lr(*, total: int, final: float) -> Callable[[int], float]:
    """A learning-rate schedule for skrl's agents, which multiply their rate by the schedule's value after every
    update: the ratio that takes the rate along ``1 - (1 - final) t / total`` (t the trainer's timestep)."""
    state = {"f": 1.0}

    def schedule(timestep: int) -> float:
        f = max(final, 1.0 - (1.0 - final) * (timestep + 1) / max(total, 1))
        ratio = f / state["f"]
        state["f"] = f
        return ratio

    return schedule


def _skrl() -> Any:
    """skrl (the ``train`` extra), or a clear error naming the extra."""
    try:
        import flax  # noqa: F401
        import jax  # noqa: F401
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
        import skrl
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ConfigError(f"cufund train needs the 'train' extra: pip install 'cufund[train]' ({e})") from None
    return skrl
