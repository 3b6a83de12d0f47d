"""Fast paths of the batch step's glue against the code they replaced, kept here as the reference.

* :func:`moma_env.vector.batch_checks.checked_actions`: the same arrays for good actions and
  the same error (type and message) for bad ones, on random inputs;
* the rewards and flags of :meth:`MomaVectorEnv._step`, one ``(agents, num_envs)`` array per
  kind, an agent's row its array: the values, dtype and shape of one array per agent.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pytest
from gymnasium import spaces

from moma_env import vector
from moma_env.vector.batch_checks import checked_actions


def _reference_checked_actions(
    actions: Mapping[str, Any], agents: Sequence[str], action_space: Callable[[str], spaces.Space], num_envs: int
) -> dict[str, np.ndarray]:
    """checked_actions as it was before its fast path (every text and check made eagerly)."""
    if not isinstance(actions, Mapping):
        raise TypeError(f"actions must be a mapping agent -> array of shape (num_envs, ...), got {type(actions).__name__}")
    unknown = sorted(set(actions) - set(agents))
    if unknown:
        raise KeyError(f"actions for unknown agent(s) {unknown}; agents are {list(agents)}")
    out = {}
    for agent in agents:
        space = action_space(agent)
        if agent not in actions:
            raise KeyError(f"no action for agent {agent!r}: every agent acts in every copy")
        if isinstance(space, spaces.Discrete):
            shape, what = (num_envs,), f"integers in [0, {space.n})"
        else:
            shape, what = (num_envs, *space.shape), "finite real numbers"
        try:
            a = np.asarray(actions[agent])
        except Exception:  # noqa: BLE001
            a = np.asarray(None)
        expected = f"an array of shape {shape} of {what} (space {space})"
        if a.shape != shape:
            raise ValueError(f"actions of {agent!r} must be {expected}, got shape {a.shape}")
        if isinstance(space, spaces.Discrete):
            if a.dtype.kind not in "iu":
                raise ValueError(f"actions of {agent!r} must be {expected}, got dtype {a.dtype}")
            bad = np.flatnonzero((a < 0) | (a >= space.n))
            if bad.size:
                raise ValueError(f"actions of {agent!r} must be {expected}; copy {int(bad[0])} has {a[bad[0]].item()!r}")
        else:
            if a.dtype.kind not in "iuf":
                raise ValueError(f"actions of {agent!r} must be {expected}, got dtype {a.dtype}")
            finite = np.isfinite(a).reshape(num_envs, -1).all(axis=1)
            if not finite.all():
                raise ValueError(f"actions of {agent!r} must be {expected}; copy {int(np.flatnonzero(~finite)[0])} is not finite")
        out[agent] = a
    return out


_SPACES = {
    "d2": spaces.Discrete(2),
    "d5": spaces.Discrete(5),
    "box": spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32),
    "box2": spaces.Box(-1.0, 1.0, shape=(2, 3), dtype=np.float32),
}


def _random_value(rng: np.random.Generator, space: spaces.Space, n: int) -> Any:
    """A row of actions for ``n`` copies, good or bad in one of the ways the checks refuse."""
    kind = rng.integers(8)
    if isinstance(space, spaces.Discrete):
        dtype = rng.choice([np.int64, np.int32, np.uint8, np.int8, np.uint64])
        a = rng.integers(0, space.n, size=n).astype(dtype)
        if kind == 1:
            a[rng.integers(n)] = space.n + rng.integers(3)  # too large
        elif kind == 2 and np.dtype(dtype).kind == "i":
            a[rng.integers(n)] = -1 - rng.integers(3)  # negative
        elif kind == 3:
            return a.astype(np.float64)  # wrong dtype
        elif kind == 4:
            return a[: n - 1] if n > 1 else a.reshape(1, 1)  # wrong shape
        elif kind == 5:
            return a.tolist()  # a list of ints: accepted as an array
        elif kind == 6:
            return object()  # nothing numpy makes an array of the right shape from
        return a
    shape = (n, *space.shape)
    a = rng.uniform(-1.0, 1.0, size=shape).astype(rng.choice([np.float32, np.float64, np.float16]))
    if kind == 1:
        a.reshape(n, -1)[rng.integers(n), rng.integers(a[0].size)] = rng.choice([np.nan, np.inf, -np.inf])
    elif kind == 2:
        return np.zeros(shape, dtype=np.int32)  # integers are finite reals
    elif kind == 3:
        return np.zeros(shape, dtype=bool)  # wrong dtype
    elif kind == 4:
        return a.reshape(n, -1)[:, :1]  # wrong shape
    elif kind == 5:
        return np.full(shape, "x")  # strings
    return a


def _outcome(function: Callable[..., Any], *args: Any) -> Any:
    try:
        return "ok", function(*args)
    except Exception as error:  # noqa: BLE001 - compared, type and message
        return "error", type(error), str(error)


@pytest.mark.parametrize("seed", range(6))
def test_checked_actions_matches_its_reference_on_random_actions(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(300):
        n = int(rng.integers(1, 6))
        agents = list(rng.permutation(list(_SPACES))[: rng.integers(1, 5)])
        actions: Any = {a: _random_value(rng, _SPACES[a], n) for a in agents}
        if rng.random() < 0.05:
            actions["stranger"] = np.zeros(n, dtype=np.int64)
        if rng.random() < 0.05 and len(agents) > 1:
            del actions[agents[-1]]
        if rng.random() < 0.02:
            actions = list(actions.items())
        expected = _outcome(_reference_checked_actions, actions, agents, _SPACES.__getitem__, n)
        got = _outcome(checked_actions, actions, agents, _SPACES.__getitem__, n)
        assert got[0] == expected[0], (got, expected)
        if got[0] == "error":
            assert got[1:] == expected[1:]
        else:
            assert list(got[1]) == list(expected[1])
            for agent in agents:
                g, e = got[1][agent], expected[1][agent]
                assert g.dtype == e.dtype and g.shape == e.shape
                assert np.array_equal(g, e, equal_nan=True)


@pytest.mark.parametrize("num_envs", [1, 3])
def test_batch_rewards_and_flags_are_one_array_per_agent_as_before(num_envs: int) -> None:
    """Each agent's rewards, terminations and truncations are what one np.array per agent made
    of the copies' values (the code replaced), through episode ends."""
    envs = vector.make("top_observer", num_envs, action_mode="switching", max_cycles=12)
    envs.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(30):
        actions = envs.sample_actions(rng)
        pending: list[Any] = []  # each copy's step, whose result is its copy's values
        for env in envs.envs:
            original = env.begin_step

            def begin_step(a: Any, original: Any = original) -> Any:
                pending.append(original(a))
                return pending[-1]

            env.begin_step = begin_step  # type: ignore[method-assign]
        try:
            _, rewards, terminations, truncations, _ = envs.step(actions)
        finally:
            for env in envs.envs:
                del env.begin_step
        seen = [step.result for step in pending]
        for a in envs.possible_agents:
            for got, index, dtype in ((rewards, 1, np.float64), (terminations, 2, bool), (truncations, 3, bool)):
                expected = np.array([out[index][a] for out in seen], dtype=dtype)
                assert got[a].dtype == expected.dtype and got[a].shape == expected.shape == (num_envs,)
                assert np.array_equal(got[a], expected)
                assert got[a].flags.c_contiguous and got[a].flags.writeable
