"""Batched MOMA envs: ``make(name, num_envs, workers=None, **options)``.

>>> from moma_env import vector                               # doctest: +SKIP
>>> envs = vector.make("top_observer", num_envs=64)           # doctest: +SKIP
>>> observations, infos = envs.reset(seed=0)                  # observations["ugv_0"].shape == (64, D)
>>> actions = {a: np.ones(64, dtype=int) for a in envs.agents}
>>> observations, rewards, terminations, truncations, infos = envs.step(actions)

``make`` returns a :class:`MomaVectorEnv` (every copy in this process) or, with
``workers=W``, a :class:`ShardedVectorEnv` (the copies split over ``W`` worker
processes; the same episodes bit for bit). Adapters: :class:`TeamVectorEnv` (the
centralised team as a Gymnasium ``VectorEnv``, what ``gymnasium.make_vec`` builds),
``moma_env.vector.torchrl.MomaTorchRLEnv`` (TorchRL, imported on use: needs the
``torchrl`` extra) and, in ``training/``,
``training.train.shared_vec_env.SharedPolicyVecEnv`` (Stable-Baselines3). See
``docs/vector.md``.
"""

from moma_env.vector.env import MomaVectorEnv
from moma_env.vector.make import BatchedEnv, make
from moma_env.vector.sharded import ShardedVectorEnv
from moma_env.vector.team import TeamVectorEnv

__all__ = ["BatchedEnv", "MomaVectorEnv", "ShardedVectorEnv", "TeamVectorEnv", "make"]
