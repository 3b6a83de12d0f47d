"""Test helper: infos that fail the test when a policy reads a ground-truth key."""

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
