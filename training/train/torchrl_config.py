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

from moma_env.config import ConfigError, check_choice, check_count, check_positive, check_range
from training.train.config import BackendTrainConfig, check_workers, config_from_dict, recorded_update_threads, run_env_options

__all__ = ["TorchRLTrainConfig", "CRITICS", "TORCHRL_ACTION_MODE"]

#: ``critic``: ``"centralised"`` (MAPPO) or ``"independent"`` (IPPO).
CRITICS = ("centralised", "independent")
#: The one action mode TorchRL runs train in (a masked categorical actor).
TORCHRL_ACTION_MODE = "switching"


@dataclass(frozen=True)
class TorchRLTrainConfig(BackendTrainConfig):
    """One TorchRL MAPPO or IPPO run: the fields of
    :class:`~training.train.config.BackendTrainConfig` (``seed``: torch's, for the network
    initialisation, action sampling and minibatches, and the env copies', copy ``i``
    resetting with ``seed + i``; ``envs``: the batch of the TorchRL env; ``n_steps``: env
    steps per copy between updates, a batch being ``n_steps x envs``; ``minibatch_size``:
    env steps, each carrying every UGV) and these.

    Attributes:
        critic: ``"centralised"`` (MAPPO) or ``"independent"`` (IPPO).
        gae_lambda, clip_range: GAE's lambda and PPO's ratio clip.
        max_grad_norm: gradients are clipped to this norm.
        torch_threads: torch's intra-op threads while collecting the batches.
        update_threads: torch's intra-op threads for the updates, which run after each
            batch while every env copy waits (None: one per usable core,
            :func:`~training.train.config.update_threads`).
        workers: None, or split the batch's copies over this many worker processes
            (:func:`moma_env.vector.make`): the same rollouts, faster with a free core
            per worker and enough copies.
    """

    envs: int = 8
    num_epochs: int = 5
    checkpoint_every: int = 50_000
    critic: str = "centralised"
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    max_grad_norm: float = 0.5
    torch_threads: int = 1
    update_threads: int | None = None
    workers: int | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        check_workers(self.workers, self.envs)
        check_choice("critic", self.critic, CRITICS)
        if self.minibatch_size > self.batch_size:
            raise ConfigError("minibatch_size", f"must be <= a batch, n_steps x envs = {self.batch_size}, got {self.minibatch_size}")
        check_range("gae_lambda", self.gae_lambda, 0.0, 1.0)
        check_positive("clip_range", self.clip_range)
        check_positive("max_grad_norm", self.max_grad_norm)
        check_count("torch_threads", self.torch_threads, 1)
        if self.update_threads is not None:
            check_count("update_threads", self.update_threads, 1)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "TorchRLTrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError. A run recorded before
        ``update_threads`` existed updated on its ``torch_threads``, which it gets."""
        return config_from_dict(cls, recorded_update_threads(data))

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
