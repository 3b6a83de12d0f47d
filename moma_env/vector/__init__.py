"""Batched MOMA envs: ``make(name, num_envs, **options)`` -> :class:`MomaVectorEnv`.

>>> from moma_env import vector                               # doctest: +SKIP
>>> envs = vector.make("top_observer", num_envs=64)           # doctest: +SKIP
>>> observations, infos = envs.reset(seed=0)                  # observations["ugv_0"].shape == (64, D)
>>> actions = {a: np.ones(64, dtype=int) for a in envs.agents}
>>> observations, rewards, terminations, truncations, infos = envs.step(actions)

Adapters: :class:`TeamVectorEnv` (the centralised team as a Gymnasium ``VectorEnv``,
what ``gymnasium.make_vec`` builds), ``moma_env.vector.torchrl.MomaTorchRLEnv``
(TorchRL, imported on use: needs the ``torchrl`` extra) and, in ``training/``,
``training.train.shared_vec_env.SharedPolicyVecEnv`` (Stable-Baselines3). See
``docs/vector.md``.
"""

from moma_env.vector.env import MomaVectorEnv, make
from moma_env.vector.team import TeamVectorEnv

__all__ = ["MomaVectorEnv", "TeamVectorEnv", "make"]
