"""Single-robot caterpillar: a robot with a backward camera and a sled it reels in.

``parallel_env(**kwargs)`` and ``env(**kwargs)`` (AEC) take the options of
:func:`moma_env.env.factory.parallel_env` and the fields of the configuration's
dataclass in :mod:`moma_env.scenarios`.
"""

from moma_env.env.factory import versioned_constructors

parallel_env, env = versioned_constructors("caterpillar_sled")
raw_env = parallel_env

__all__ = ["parallel_env", "env", "raw_env"]
