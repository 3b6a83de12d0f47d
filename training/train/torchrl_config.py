"""What a TorchRL training run is: :class:`TorchRLTrainConfig`, validated at the boundary (no torch import).

Multi-agent PPO on the batched env's TorchRL adapter
(:class:`moma_env.vector.torchrl.MomaTorchRLEnv`), in switching mode with the motion
rules' action masks: one actor shared by every UGV (each acting on its own
observation), and a critic that is either centralised (MAPPO: every UGV's value from
the whole team's observations) or independent (IPPO: from the UGV's own). The UAV
observer is flown by its tracking controller (``observer_agent=False``), a new random
layout at every reset, as on the other routes. Steps count env steps (one step of the
team).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from moma_env.config import ConfigError, check_bool, check_choice, check_count, check_non_negative, check_positive, check_range
from moma_env.env.config import RewardConfig
from moma_env.scenarios import CONFIGURATIONS
from moma_env.tasks import TASKS
from training.train.config import config_from_dict, config_to_dict, run_env_options

__all__ = ["TorchRLTrainConfig", "CRITICS", "TORCHRL_ACTION_MODE"]

#: ``critic``: ``"centralised"`` (MAPPO) or ``"independent"`` (IPPO).
CRITICS = ("centralised", "independent")
#: The one action mode TorchRL runs train in (a masked categorical actor).
TORCHRL_ACTION_MODE = "switching"


@dataclass(frozen=True)
class TorchRLTrainConfig:
    """One TorchRL MAPPO or IPPO run.

    Attributes:
        scenario: configuration or task name.
        steps: total env steps to collect.
        envs: env copies stepped together (the batch of the TorchRL env).
        seed: seed of torch (network initialisation, action sampling, minibatches)
            and of the env copies (copy ``i`` resets with ``seed + i``).
        critic: ``"centralised"`` (MAPPO) or ``"independent"`` (IPPO).
        max_cycles: training episode length in steps (None: the scenario's).
        rewards: reward weights (None: the scenario's).
        net_arch: hidden layer sizes of the actor and the critic (tanh).
        n_steps: env steps per copy between updates (a batch is ``n_steps x envs``).
        minibatch_size: env steps per minibatch (each with every UGV).
        num_epochs: passes over each batch.
        learning_rate, gamma, gae_lambda, clip_range, ent_coef: PPO's step size,
            discount, GAE's lambda, ratio clip and entropy bonus.
        max_grad_norm: gradients are clipped to this norm.
        torch_threads: torch's intra-op threads while training.
        checkpoint_every: env steps between checkpoints (the last is always saved).
        eval_every: env steps between held-out evaluations (0: never), also run at the end.
        eval_episodes: episodes per evaluation.
        eval_seed: seed of the first held-out episode.
        eval_max_cycles: episode length of the evaluations (None: the scenario's).
        eval_sample_actions: the evaluations sample actions instead of taking the mode.
    """

    scenario: str
    steps: int = 100_000
    envs: int = 8
    seed: int = 0
    critic: str = "centralised"
    max_cycles: int | None = None
    rewards: RewardConfig | None = None
    net_arch: tuple[int, ...] = (64, 64)
    n_steps: int = 256
    minibatch_size: int = 256
    num_epochs: int = 5
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.01
    max_grad_norm: float = 0.5
    torch_threads: int = 1
    checkpoint_every: int = 50_000
    eval_every: int = 0
    eval_episodes: int = 5
    eval_seed: int = 10_000
    eval_max_cycles: int | None = None
    eval_sample_actions: bool = False

    def __post_init__(self) -> None:
        check_choice("scenario", self.scenario, sorted(CONFIGURATIONS) + sorted(TASKS))
        check_count("steps", self.steps, 1)
        check_count("envs", self.envs, 1)
        check_count("seed", self.seed, 0)
        check_choice("critic", self.critic, CRITICS)
        for name in ("max_cycles", "eval_max_cycles"):
            if getattr(self, name) is not None:
                check_count(name, getattr(self, name), 1)
        if self.rewards is not None and not isinstance(self.rewards, RewardConfig):
            raise ConfigError("rewards", f"must be a RewardConfig or None, got {type(self.rewards).__name__}")
        if not isinstance(self.net_arch, tuple) or not self.net_arch:
            raise ConfigError("net_arch", f"must be a non-empty tuple of layer sizes, got {self.net_arch!r}")
        for k, size in enumerate(self.net_arch):
            check_count(f"net_arch[{k}]", size, 1)
        check_count("n_steps", self.n_steps, 1)
        check_count("minibatch_size", self.minibatch_size, 1)
        if self.minibatch_size > self.batch_size:
            raise ConfigError("minibatch_size", f"must be <= a batch, n_steps x envs = {self.batch_size}, got {self.minibatch_size}")
        check_count("num_epochs", self.num_epochs, 1)
        check_positive("learning_rate", self.learning_rate)
        check_range("gamma", self.gamma, 0.0, 1.0)
        check_range("gae_lambda", self.gae_lambda, 0.0, 1.0)
        check_positive("clip_range", self.clip_range)
        check_non_negative("ent_coef", self.ent_coef)
        check_positive("max_grad_norm", self.max_grad_norm)
        check_count("torch_threads", self.torch_threads, 1)
        check_count("checkpoint_every", self.checkpoint_every, 1)
        check_count("eval_every", self.eval_every, 0)
        check_count("eval_episodes", self.eval_episodes, 1)
        check_count("eval_seed", self.eval_seed, 0)
        check_bool("eval_sample_actions", self.eval_sample_actions)

    @property
    def batch_size(self) -> int:
        """Env steps collected between two updates (``n_steps x envs``)."""
        return self.n_steps * self.envs

    @property
    def action_mode(self) -> str:
        """The env action mode (always :data:`TORCHRL_ACTION_MODE`)."""
        return TORCHRL_ACTION_MODE

    @property
    def env_options(self) -> dict[str, Any]:
        """Options of ``parallel_env`` (and so of the TorchRL adapter) for the run's envs."""
        return run_env_options(TORCHRL_ACTION_MODE, self.max_cycles, self.rewards)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest (tuples as lists)."""
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "TorchRLTrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError."""
        return config_from_dict(cls, data)
