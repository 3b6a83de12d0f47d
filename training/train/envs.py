"""The vectorised training envs of a :class:`~training.train.config.TrainConfig`.

* ``shared`` route: :class:`~training.train.shared_vec_env.SharedPolicyVecEnv`
  (K copies, one slot per UGV; in this process on one ``moma_env.vector.MomaVectorEnv``,
  or one worker process per copy with ``subproc``).
* ``centralised`` route: K :class:`moma_env.env.centralised.CentralisedTeamEnv`
  each in SB3's ``Monitor`` (episode statistics), in ``DummyVecEnv`` or, with
  ``subproc``, ``SubprocVecEnv``. Their rewards are rounded to float32 first:
  ``DummyVecEnv`` stores rewards as float32 and ``SubprocVecEnv`` as float64,
  so without the rounding ``--subproc`` would train different weights.

Both are seeded with ``seed`` through ``VecEnv.seed`` (slot i resets first with
``seed + i``); ``normalize`` adds ``VecNormalize`` (observations and rewards,
discounted with the run's gamma), or restores its statistics from a file.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import SupportsFloat

import numpy as np
from gymnasium.wrappers import TransformReward
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize

from moma_env.env.factory import centralised_env
from training.train.config import TrainConfig
from moma_env.vector.sharded import default_start_method
from training.train.shared_vec_env import SharedPolicyVecEnv
from training.train.team_slots import EnvSpec

__all__ = ["env_spec", "make_vec_env", "wrap_normalisation"]


def env_spec(config: TrainConfig) -> EnvSpec:
    """What one env copy of the run is built from."""
    return EnvSpec(config.scenario, config.env_options)


def _float32(reward: SupportsFloat) -> float:
    """``reward`` rounded to float32 precision (the precision of SB3's reward buffers)."""
    return float(np.float32(reward))


def _monitored_team_env(spec: EnvSpec) -> Monitor:
    """One centralised team env, rewards in float32 precision, with episode statistics
    (module level: picklable for workers)."""
    return Monitor(TransformReward(centralised_env(spec.configuration, **spec.options), _float32))


def make_vec_env(config: TrainConfig, seed: int) -> VecEnv:
    """The run's K env copies through its route, seeded with ``seed`` (without normalisation)."""
    spec = env_spec(config)
    if config.route == "shared":
        venv: VecEnv = SharedPolicyVecEnv(spec, config.envs, subproc=config.subproc, workers=config.workers)
    else:
        fns = [functools.partial(_monitored_team_env, spec) for _ in range(config.envs)]
        venv = SubprocVecEnv(fns, start_method=default_start_method()) if config.subproc else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


def wrap_normalisation(venv: VecEnv, config: TrainConfig, stats: Path | None = None) -> VecEnv:
    """``venv`` in ``VecNormalize`` if the run normalises (statistics from ``stats`` when resuming)."""
    if not config.normalize:
        return venv
    if stats is not None:
        return VecNormalize.load(str(stats), venv)
    return VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=config.gamma)
