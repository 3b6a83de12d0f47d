"""The vectorised training envs of a :class:`~training.train.config.TrainConfig`.

Both routes step one batched env of K copies (``moma_env.vector``: in this process,
split over ``workers`` processes, or one process per copy with ``subproc``), through
the SB3 adapters of :mod:`training.train.shared_vec_env`:

* ``shared`` route: :class:`~training.train.shared_vec_env.SharedPolicyVecEnv`, one
  slot per UGV;
* ``centralised`` route: :class:`~training.train.shared_vec_env.TeamVecEnv`, one slot
  per copy, each the centralised team env
  (:class:`moma_env.env.centralised.CentralisedTeamEnv`) bit for bit.

Both are seeded with ``seed`` through ``VecEnv.seed`` (slot i resets first with
``seed + i``); ``normalize`` adds ``VecNormalize`` (observations and rewards,
discounted with the run's gamma), or restores its statistics from a file.
"""

from __future__ import annotations

from pathlib import Path

from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from training.train.config import TrainConfig
from training.train.shared_vec_env import SharedPolicyVecEnv, TeamVecEnv
from training.train.team_slots import SLOT_INFO_KEYS, EnvSpec

__all__ = ["env_spec", "make_vec_env", "wrap_normalisation"]


def env_spec(config: TrainConfig) -> EnvSpec:
    """What one env copy of the run is built from."""
    return EnvSpec(config.scenario, config.env_options)


def make_vec_env(config: TrainConfig, seed: int) -> VecEnv:
    """The run's K env copies through its route, seeded with ``seed`` (without normalisation).

    The copies' infos carry only what the slots read (:data:`~training.train.team_slots.SLOT_INFO_KEYS`:
    the action masks and the robots' static flags; SB3's own keys are added to them): the
    rest of a copy's infos (truth, estimates, covariances, events, reward terms) is not
    built nor sent from the worker processes. What is learned is the same, bit for bit.
    """
    adapter = SharedPolicyVecEnv if config.route == "shared" else TeamVecEnv
    spec = env_spec(config)
    spec = EnvSpec(spec.configuration, {**spec.options, "info_keys": SLOT_INFO_KEYS})
    venv: VecEnv = adapter(spec, config.envs, subproc=config.subproc, workers=config.workers)
    venv.seed(seed)
    return venv


def wrap_normalisation(venv: VecEnv, config: TrainConfig, stats: Path | None = None) -> VecEnv:
    """``venv`` in ``VecNormalize`` if the run normalises: fresh, or with the statistics
    saved in ``stats`` (resuming, or starting from another run's, ``--init-from``), still
    updating, at the run's discount."""
    if not config.normalize:
        return venv
    if stats is None:
        return VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=config.gamma)
    loaded = VecNormalize.load(str(stats), venv)
    loaded.training = True
    loaded.gamma = config.gamma
    return loaded
