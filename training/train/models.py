"""Construction of the Stable-Baselines3 model of a run.

Hyperparameters come from :class:`~training.train.config.TrainConfig` (network
sizes, rollout length, batch size, learning rate, discount); the rest are SB3's
defaults. :func:`training_logger` is where SB3's own training metrics go (never
SB3's default of a new folder in the system's temporary directory per ``learn``).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import CSVOutputFormat, KVWriter, Logger
from stable_baselines3.common.vec_env import VecEnv

from agents.learned import sb3_class
from training.train.config import ALGORITHMS, TrainConfig

__all__ = ["algorithm_class", "build_model", "training_logger"]

#: Algorithms trained with PPO's hyperparameters.
_PPO_LIKE = frozenset({"ppo", "maskable_ppo"})


def algorithm_class(algo: str) -> type[BaseAlgorithm]:
    """The SB3 (or sb3-contrib) class of a CLI algorithm name."""
    return sb3_class(ALGORITHMS[algo])


def training_logger(out: Path | None, start: int = 0) -> Logger:
    """The SB3 logger of a training session that starts at timestep ``start`` in run folder ``out``.

    SB3's metrics (``rollout/``, ``train/``, ``time/``, our ``eval/``) go to
    ``<out>/logs/progress_<start>.csv``, one file per session (a resumed run adds
    a file, it never overwrites an earlier session's), and to
    ``<out>/tensorboard/run_<start>`` when the ``tensorboard`` package can be
    imported (it is not a dependency). ``out=None``: a logger that writes nothing
    (the benchmark). Close it after ``learn``.
    """
    if out is None:
        return Logger(folder=None, output_formats=[])
    logs = out / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    formats: list[KVWriter] = [CSVOutputFormat(str(logs / f"progress_{start:012d}.csv"))]
    if importlib.util.find_spec("tensorboard") is not None:
        from stable_baselines3.common.logger import TensorBoardOutputFormat

        formats.append(TensorBoardOutputFormat(str(out / "tensorboard" / f"run_{start:012d}")))
    return Logger(folder=str(logs), output_formats=formats)


def _hyperparameters(config: TrainConfig, n_slots: int) -> dict[str, Any]:
    net = list(config.net_arch)
    kwargs: dict[str, Any] = {"learning_rate": config.learning_rate, "gamma": config.gamma}
    if config.algo in _PPO_LIKE:
        rollout = config.n_steps * n_slots
        kwargs |= {"n_steps": config.n_steps, "batch_size": min(config.minibatch_size(rollout), rollout), "n_epochs": 5, "ent_coef": config.ent_coef,
                   "policy_kwargs": {"net_arch": {"pi": net, "vf": net}}}
    elif config.algo == "a2c":
        kwargs |= {"n_steps": config.n_steps, "ent_coef": config.ent_coef, "policy_kwargs": {"net_arch": {"pi": net, "vf": net}}}
    else:  # dqn, sac, td3: off-policy
        kwargs |= {"batch_size": config.minibatch_size(), "buffer_size": config.buffer_size,
                   "learning_starts": min(1000, config.steps // 10), "policy_kwargs": {"net_arch": net}}
    return kwargs


def build_model(config: TrainConfig, venv: VecEnv) -> BaseAlgorithm:
    """A new model of ``config.algo`` on ``venv``, seeded with ``config.seed``, on the CPU
    (give it a :func:`training_logger` before ``learn``)."""
    cls = algorithm_class(config.algo)
    kwargs = _hyperparameters(config, venv.num_envs)
    policy: Any = "MlpPolicy"
    if config.network == "team":
        from agents.team_network import MaskableTeamActorCriticPolicy, TeamActorCriticPolicy

        policy = MaskableTeamActorCriticPolicy if config.algo == "maskable_ppo" else TeamActorCriticPolicy
        kwargs["policy_kwargs"] = {"net_arch": list(config.net_arch), "n_agents": len(venv.action_space.nvec)}
    return cls(policy, venv, seed=config.seed, device="cpu", verbose=0, **kwargs)
