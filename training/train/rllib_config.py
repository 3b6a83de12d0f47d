"""What an RLlib training run is: :class:`RllibTrainConfig`, validated at the boundary (no Ray import).

PPO on RLlib's new API stack (:func:`moma_env.integrations.rllib.ppo_config`): one
policy shared by every UGV, the UAV observer flown by its tracking controller
(``observer_agent=False``, as on the Stable-Baselines3 route), a new random layout at
every reset, action masks in switching mode. Steps count env steps (one step of the
team), as RLlib samples them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from moma_env.config import ConfigError, check_bool, check_choice, check_count, check_non_negative, check_positive, check_range
from moma_env.env.config import ACTION_MODES, RewardConfig
from moma_env.scenarios import CONFIGURATIONS
from moma_env.tasks import TASKS
from training.train.config import config_from_dict, config_to_dict, run_env_options

__all__ = ["RllibTrainConfig", "RLLIB_ROUTES"]

#: How the env reaches RLlib (:data:`moma_env.integrations.rllib.ROUTES`).
RLLIB_ROUTES = ("pettingzoo", "vector")


@dataclass(frozen=True)
class RllibTrainConfig:
    """One RLlib PPO run.

    Attributes:
        scenario: configuration or task name.
        steps: total env steps to sample.
        num_env_runners: remote env runners (Ray actors; 0: sample in the driver).
        envs: env copies per env runner.
        env_route: ``"pettingzoo"`` (RLlib's PettingZoo wrapper, copies stepped one by
            one) or ``"vector"`` (the batched env, cameras measured together).
        seed: RLlib's seed.
        action_mode: ``"switching"`` (masked) or ``"velocity"``.
        max_cycles: training episode length in steps (None: the scenario's).
        rewards: reward weights (None: the scenario's).
        net_arch: hidden layer sizes of the policy and value networks.
        n_steps: rollout fragment length per copy (env steps).
        batch_size: train batch size per update (agent steps of RLlib's learner).
        minibatch_size: minibatch size.
        num_epochs: passes over each batch.
        learning_rate, gamma, ent_coef: PPO's step size, discount, entropy bonus.
        checkpoint_every: env steps between checkpoints (the last is always saved).
        eval_every: env steps between held-out evaluations (0: never), also run at the end.
        eval_episodes: episodes per evaluation.
        eval_seed: seed of the first held-out episode.
        eval_max_cycles: episode length of the evaluations (None: the scenario's).
        eval_sample_actions: the evaluations sample actions instead of taking the mode.
    """

    scenario: str
    steps: int = 100_000
    num_env_runners: int = 0
    envs: int = 2
    env_route: str = "pettingzoo"
    seed: int = 0
    action_mode: str = "switching"
    max_cycles: int | None = None
    rewards: RewardConfig | None = None
    net_arch: tuple[int, ...] = (64, 64)
    n_steps: int = 256
    batch_size: int = 1024
    minibatch_size: int = 256
    num_epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.995
    ent_coef: float = 0.01
    checkpoint_every: int = 20_000
    eval_every: int = 0
    eval_episodes: int = 5
    eval_seed: int = 10_000
    eval_max_cycles: int | None = None
    eval_sample_actions: bool = False

    def __post_init__(self) -> None:
        check_choice("scenario", self.scenario, sorted(CONFIGURATIONS) + sorted(TASKS))
        check_count("steps", self.steps, 1)
        check_count("num_env_runners", self.num_env_runners, 0)
        check_count("envs", self.envs, 1)
        check_choice("env_route", self.env_route, RLLIB_ROUTES)
        check_count("seed", self.seed, 0)
        check_choice("action_mode", self.action_mode, ACTION_MODES)
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
        check_count("batch_size", self.batch_size, 1)
        check_count("minibatch_size", self.minibatch_size, 1)
        if self.minibatch_size > self.batch_size:
            raise ConfigError("minibatch_size", f"must be <= batch_size ({self.batch_size}), got {self.minibatch_size}")
        check_count("num_epochs", self.num_epochs, 1)
        check_positive("learning_rate", self.learning_rate)
        check_range("gamma", self.gamma, 0.0, 1.0)
        check_non_negative("ent_coef", self.ent_coef)
        check_count("checkpoint_every", self.checkpoint_every, 1)
        check_count("eval_every", self.eval_every, 0)
        check_count("eval_episodes", self.eval_episodes, 1)
        check_count("eval_seed", self.eval_seed, 0)
        check_bool("eval_sample_actions", self.eval_sample_actions)

    @property
    def env_options(self) -> dict[str, Any]:
        """The registered creator's ``env_config`` (options of ``parallel_env``)."""
        return run_env_options(self.action_mode, self.max_cycles, self.rewards)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest (tuples as lists)."""
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "RllibTrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError."""
        return config_from_dict(cls, data)
