"""What an RLlib training run is: :class:`RllibTrainConfig`, validated at the boundary (no Ray import).

PPO on RLlib's new API stack (:func:`moma_env.integrations.rllib.ppo_config`): one
policy shared by every UGV, the UAV observer flown by its tracking controller
(``observer_agent=False``, as on the Stable-Baselines3 route), a new random layout at
every reset, action masks in switching mode. Steps count env steps (one step of the
team), as RLlib samples them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from moma_env.config import ConfigError, check_choice, check_count
from moma_env.env.config import ACTION_MODES
from training.train.config import BackendTrainConfig, run_env_options

__all__ = ["RllibTrainConfig", "RLLIB_ROUTES"]

#: How the env reaches RLlib (:data:`moma_env.integrations.rllib.ROUTES`).
RLLIB_ROUTES = ("pettingzoo", "vector")


@dataclass(frozen=True)
class RllibTrainConfig(BackendTrainConfig):
    """One RLlib PPO run: the fields of :class:`~training.train.config.BackendTrainConfig`
    (``seed``: RLlib's; ``envs``: copies per env runner; ``n_steps``: the rollout fragment
    per copy) and these.

    Attributes:
        num_env_runners: remote env runners (Ray actors; 0: sample in the driver).
        env_route: ``"pettingzoo"`` (RLlib's PettingZoo wrapper, copies stepped one by
            one) or ``"vector"`` (the batched env, cameras measured together).
        action_mode: ``"switching"`` (masked) or ``"velocity"``.
        batch_size: train batch size per update (agent steps of RLlib's learner).
    """

    num_env_runners: int = 0
    env_route: str = "pettingzoo"
    action_mode: str = "switching"
    batch_size: int = 1024

    def __post_init__(self) -> None:
        super().__post_init__()
        check_count("num_env_runners", self.num_env_runners, 0)
        check_choice("env_route", self.env_route, RLLIB_ROUTES)
        check_choice("action_mode", self.action_mode, ACTION_MODES)
        check_count("batch_size", self.batch_size, 1)
        if self.minibatch_size > self.batch_size:
            raise ConfigError("minibatch_size", f"must be <= batch_size ({self.batch_size}), got {self.minibatch_size}")

    @property
    def env_options(self) -> dict[str, Any]:
        """The registered creator's ``env_config`` (options of ``parallel_env``)."""
        return run_env_options(self.action_mode, self.max_cycles, self.rewards)
