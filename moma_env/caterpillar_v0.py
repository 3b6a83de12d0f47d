"""Two-robot caterpillar: the follower's forward camera sees a board on the leader's back.

``parallel_env(**kwargs)`` and ``env(**kwargs)`` (AEC) take the options of
:func:`moma_env.env.factory.parallel_env` and the fields of the configuration's
dataclass in :mod:`moma_env.scenarios`.
"""

from moma_env.env.factory import versioned_constructors

parallel_env, env = versioned_constructors("caterpillar")
raw_env = parallel_env

__all__ = ["parallel_env", "env", "raw_env"]
