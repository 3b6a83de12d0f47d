"""Construction of the Stable-Baselines3 model of a run.

Hyperparameters come from :class:`~training.train.config.TrainConfig` (network
sizes, rollout length, batch size, learning rate, discount); the rest are SB3's
defaults. TensorBoard logs go to ``<out>/tensorboard`` only when the
``tensorboard`` package can be imported.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import stable_baselines3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from training.train.config import ALGORITHMS, TrainConfig

__all__ = ["algorithm_class", "build_model", "tensorboard_dir"]

#: Algorithms whose rollout length is ``n_steps`` per slot.
_ON_POLICY = frozenset({"ppo", "a2c"})


def algorithm_class(algo: str) -> type[BaseAlgorithm]:
    """The SB3 class of a CLI algorithm name."""
    return getattr(stable_baselines3, ALGORITHMS[algo])


def tensorboard_dir(out: Path) -> str | None:
    """``<out>/tensorboard`` if tensorboard is importable, else None (no TensorBoard logs)."""
    return str(out / "tensorboard") if importlib.util.find_spec("tensorboard") is not None else None


def _hyperparameters(config: TrainConfig, n_slots: int) -> dict[str, Any]:
    net = list(config.net_arch)
    kwargs: dict[str, Any] = {"learning_rate": config.learning_rate, "gamma": config.gamma}
    if config.algo == "ppo":
        rollout = config.n_steps * n_slots
        kwargs |= {"n_steps": config.n_steps, "batch_size": min(config.batch_size, rollout), "n_epochs": 5, "ent_coef": config.ent_coef,
                   "policy_kwargs": {"net_arch": {"pi": net, "vf": net}}}
    elif config.algo == "a2c":
        kwargs |= {"n_steps": config.n_steps, "ent_coef": config.ent_coef, "policy_kwargs": {"net_arch": {"pi": net, "vf": net}}}
    else:  # dqn, sac, td3: off-policy
        kwargs |= {"batch_size": config.batch_size, "buffer_size": config.buffer_size,
                   "learning_starts": min(1000, config.steps // 10), "policy_kwargs": {"net_arch": net}}
    return kwargs


def build_model(config: TrainConfig, venv: VecEnv, out: Path) -> BaseAlgorithm:
    """A new model of ``config.algo`` on ``venv``, seeded with ``config.seed``, on the CPU."""
    cls = algorithm_class(config.algo)
    return cls(
        "MlpPolicy",
        venv,
        seed=config.seed,
        device="cpu",
        verbose=0,
        tensorboard_log=tensorboard_dir(out),
        **_hyperparameters(config, venv.num_envs),
    )
