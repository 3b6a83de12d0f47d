"""Test helpers: infos that fail the test when a policy reads a ground-truth key, and a
policy's actions over one seeded episode."""

from collections.abc import Iterator, Mapping
from typing import Any

from agents.policies import FORBIDDEN_INFO_KEYS


class TruthGuardedInfo(Mapping):
    """An agent's info dict that raises when a policy reads a ground-truth key."""

    def __init__(self, info: Mapping[str, Any]):
        self._info = info

    def __getitem__(self, key: str) -> Any:
        if key in FORBIDDEN_INFO_KEYS:
            raise AssertionError(f"the policy read the ground-truth info key {key!r}")
        return self._info[key]

    def __iter__(self) -> Iterator[str]:
        return (k for k in self._info if k not in FORBIDDEN_INFO_KEYS)

    def __len__(self) -> int:
        return sum(1 for k in self._info if k not in FORBIDDEN_INFO_KEYS)


def guarded(infos: Mapping[str, Mapping[str, Any]]) -> dict[str, TruthGuardedInfo]:
    """Every agent's info, truth-guarded."""
    return {agent: TruthGuardedInfo(info) for agent, info in infos.items()}


def episode_actions(policy: Any, scenario: str, options: Mapping[str, Any], seed: int, steps: int) -> list[dict]:
    """Every action of ``policy`` (as plain lists) over one episode of ``parallel_env(scenario,
    **options)`` reset with ``seed`` and cut at ``steps`` steps, the policy seeing truth-guarded infos."""
    import numpy as np

    from moma_env.env.factory import parallel_env

    env = parallel_env(scenario, **(dict(options) | {"max_cycles": steps}))
    observations, infos = env.reset(seed=seed)
    policy.reset(env, seed=seed)
    out = []
    while env.agents:
        actions = policy.act(observations, guarded(infos))
        out.append({a: np.asarray(v).tolist() for a, v in actions.items()})
        observations, _, _, _, infos = env.step(actions)
    return out
