"""Top observer: N >= 2 UGVs with boards on top under one UAV observer.

``parallel_env(**kwargs)`` and ``env(**kwargs)`` (AEC) take the options of
:func:`moma_env.env.factory.parallel_env` and the fields of the configuration's
dataclass in :mod:`moma_env.scenarios`.
"""

from moma_env.env.factory import versioned_constructors

parallel_env, env = versioned_constructors("top_observer")
raw_env = parallel_env

__all__ = ["parallel_env", "env", "raw_env"]
