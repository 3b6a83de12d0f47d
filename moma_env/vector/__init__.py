"""Batched MOMA envs: ``make(name, num_envs, **options)`` -> :class:`MomaVectorEnv`.

>>> from moma_env import vector                               # doctest: +SKIP
>>> envs = vector.make("top_observer", num_envs=64)           # doctest: +SKIP
>>> observations, infos = envs.reset(seed=0)                  # observations["ugv_0"].shape == (64, D)
>>> actions = {a: np.ones(64, dtype=int) for a in envs.agents}
>>> observations, rewards, terminations, truncations, infos = envs.step(actions)
"""

from moma_env.vector.env import MomaVectorEnv, make

__all__ = ["MomaVectorEnv", "make"]
