"""The boundary checks every batched env shares: seeds, copy indices, action arrays, the autoreset mode.

:class:`~moma_env.vector.env.MomaVectorEnv` (copies in this process) and
:class:`~moma_env.vector.sharded.ShardedVectorEnv` (copies in worker processes)
take the same arguments and refuse the same bad ones with the same messages,
before any copy is touched.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from numbers import Integral
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from moma_env.config import ConfigError
from moma_env.env.parallel import checked_seed

__all__ = [
    "checked_actions", "checked_autoreset_mode", "checked_count", "checked_index", "checked_reset_mask", "copy_options", "copy_seeds",
    "random_actions", "refuse_finished_copies", "require_same_step",
]


def checked_count(name: str, value: object) -> int:
    """``value`` as an int if it is an integer >= 1, else ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Integral) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def checked_autoreset_mode(value: object) -> AutoresetMode:
    """``value`` as a Gymnasium ``AutoresetMode`` (a member or its value, e.g. ``"NextStep"``),
    else ConfigError naming ``autoreset_mode``."""
    if isinstance(value, AutoresetMode):
        return value
    try:
        return AutoresetMode(value)
    except ValueError:
        raise ConfigError(
            "autoreset_mode", f"must be a gymnasium.vector.AutoresetMode or one of {[m.value for m in AutoresetMode]}, got {value!r}"
        ) from None


def require_same_step(options: Mapping[str, Any], adapter: str) -> None:
    """ConfigError naming ``autoreset_mode`` unless the batched env of ``options`` (what
    :func:`~moma_env.vector.make` takes) resets a finished copy in the step that ends its
    episode, the only mode ``adapter`` reads; checked before anything is built."""
    mode = checked_autoreset_mode(options.get("autoreset_mode", AutoresetMode.SAME_STEP))
    if mode is not AutoresetMode.SAME_STEP:
        raise ConfigError(
            "autoreset_mode", f"{adapter} reads the SameStep autoreset (final observations in the infos), got {mode.value!r}"
        )


def refuse_finished_copies(mode: AutoresetMode, ended: set[int]) -> None:
    """Under ``AutoresetMode.DISABLED``, RuntimeError naming the copies in ``ended`` (their
    episodes ended and they were not reset since), before a step."""
    if ended and mode is AutoresetMode.DISABLED:
        raise RuntimeError(
            f"copies {sorted(ended)} ended their episodes and autoreset_mode is DISABLED: reset them first "
            "(reset_at(i), or reset(options={'reset_mask': mask}))"
        )


def checked_reset_mask(mask: object, num_envs: int) -> np.ndarray:
    """Gymnasium's ``options["reset_mask"]``: a bool array ``(num_envs,)`` with a True, which
    copies to reset (a copy of it); ValueError naming ``options['reset_mask']`` otherwise."""
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (num_envs,):
        got = f"{type(mask).__name__} {getattr(mask, 'dtype', '')} {getattr(mask, 'shape', '')}".strip()
        raise ValueError(f"options['reset_mask'] must be a numpy bool array of shape ({num_envs},), got {got}")
    if not mask.any():
        raise ValueError("options['reset_mask'] must select at least one copy")
    return mask.copy()


def copy_seeds(seed: int | Sequence[int] | None, num_envs: int) -> list[int | None]:
    """Each copy's reset seed (Gymnasium's vector rule): ``seed + i`` for copy ``i``,
    the sequence itself if ``seed`` is one of ``num_envs`` seeds, or None for every copy."""
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, Sequence) and not isinstance(seed, str):
        if len(seed) != num_envs:
            raise ValueError(f"seed: a sequence must hold num_envs={num_envs} seeds, got {len(seed)}")
        return [checked_seed(s) for s in seed]
    base = checked_seed(seed)
    return [base + i for i in range(num_envs)]  # type: ignore[operator]


def copy_options(options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None, num_envs: int) -> list[Any]:
    """Each copy's reset options: ``options`` itself for every copy (None or a mapping), or
    the sequence of ``num_envs`` per-copy options (each None or a mapping)."""
    if options is None or isinstance(options, Mapping):
        return [options] * num_envs
    if isinstance(options, Sequence) and not isinstance(options, (str, bytes)):
        if len(options) != num_envs:
            raise ValueError(f"options: a sequence must hold num_envs={num_envs} entries (one per copy), got {len(options)}")
        for i, entry in enumerate(options):
            if entry is not None and not isinstance(entry, Mapping):
                raise TypeError(f"options[{i}] must be None or a mapping, got {type(entry).__name__}")
        return list(options)
    raise TypeError(f"options must be None, a mapping or a sequence of num_envs of them, got {type(options).__name__}")


def checked_index(index: object, num_envs: int) -> int:
    """``index`` as an int if it names a copy (``0 <= index < num_envs``), else IndexError."""
    if isinstance(index, (bool, np.bool_)) or not isinstance(index, Integral) or not 0 <= index < num_envs:
        raise IndexError(f"copy index must be an integer in [0, {num_envs}), got {index!r}")
    return int(index)


def checked_actions(
    actions: Mapping[str, Any], agents: Sequence[str], action_space: Callable[[str], spaces.Space], num_envs: int
) -> dict[str, np.ndarray]:
    """``actions`` (agent -> ``(num_envs, *act_shape)``) as arrays, every agent's checked:
    a Discrete agent's integers in range, a Box agent's finite reals. Errors name the
    agent, the expected shape and dtype and, for a bad value, the first bad copy."""
    if not isinstance(actions, Mapping):
        raise TypeError(f"actions must be a mapping agent -> array of shape (num_envs, ...), got {type(actions).__name__}")
    for key in actions:
        if key not in agents:
            unknown = sorted(set(actions) - set(agents))
            raise KeyError(f"actions for unknown agent(s) {unknown}; agents are {list(agents)}")
    out = {}
    for agent in agents:
        space = action_space(agent)
        if agent not in actions:
            raise KeyError(f"no action for agent {agent!r}: every agent acts in every copy")
        discrete = isinstance(space, spaces.Discrete)
        shape = (num_envs,) if discrete else (num_envs, *space.shape)
        try:
            a = np.asarray(actions[agent])
        except Exception:  # noqa: BLE001 - whatever numpy refuses is refused below
            a = np.asarray(None)
        if a.shape != shape:
            raise ValueError(f"actions of {agent!r} must be {_expected(space, shape)}, got shape {a.shape}")
        kind = a.dtype.kind
        if discrete:
            if kind not in "iu":
                raise ValueError(f"actions of {agent!r} must be {_expected(space, shape)}, got dtype {a.dtype}")
            # The range checked on Python ints (a batch's row of a few integers: cheaper
            # than numpy's comparisons); the first bad copy is found only for the error.
            values = a.tolist()
            if min(values) < 0 or max(values) >= int(space.n):
                bad = np.flatnonzero((a < 0) | (a >= space.n))
                raise ValueError(f"actions of {agent!r} must be {_expected(space, shape)}; copy {int(bad[0])} has {a[bad[0]].item()!r}")
        else:
            if kind not in "iuf":
                raise ValueError(f"actions of {agent!r} must be {_expected(space, shape)}, got dtype {a.dtype}")
            # Integers are always finite; the bad copy is looked for only when one is not.
            if kind == "f" and not np.isfinite(a).all():
                finite = np.isfinite(a).reshape(num_envs, -1).all(axis=1)
                raise ValueError(f"actions of {agent!r} must be {_expected(space, shape)}; copy {int(np.flatnonzero(~finite)[0])} is not finite")
        out[agent] = a
    return out


def _expected(space: spaces.Space, shape: tuple[int, ...]) -> str:
    """What :func:`checked_actions` expects of an agent's actions, for its errors (made only
    for an error: a space's text costs more than the checks)."""
    what = f"integers in [0, {space.n})" if isinstance(space, spaces.Discrete) else "finite real numbers"
    return f"an array of shape {shape} of {what} (space {space})"


def random_actions(
    agents: Sequence[str], action_space: Callable[[str], spaces.Space], num_envs: int, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Uniform random actions of every agent for every copy, drawn from ``rng``: integers
    ``(num_envs,)`` for a Discrete agent, float32 ``(num_envs, *shape)`` in [-1, 1] for a Box one."""
    out = {}
    for agent in agents:
        space = action_space(agent)
        if isinstance(space, spaces.Discrete):
            out[agent] = rng.integers(0, space.n, size=num_envs)
        else:
            out[agent] = rng.uniform(-1.0, 1.0, size=(num_envs, *space.shape)).astype(np.float32)
    return out
