"""Multi-robot caterpillar: N robots in a file, each camera sees the board ahead.

``parallel_env(**kwargs)`` and ``env(**kwargs)`` (AEC) take the options of
:func:`moma_env.env.factory.parallel_env` and the fields of the configuration's
dataclass in :mod:`moma_env.scenarios`.
"""

from moma_env.env.factory import versioned_constructors

parallel_env, env = versioned_constructors("caterpillar_multi")
raw_env = parallel_env

__all__ = ["parallel_env", "env", "raw_env"]
