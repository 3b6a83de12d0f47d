"""The unit of work of a sweep: one cell's episode through the evaluation harness.

:func:`run_cell` loads the cell's policy afresh (so nothing carries over from another
cell of the same task), picks the env options the policy fits exactly as ``moma-env
evaluate`` does (a trained policy's ``env_options``, else the built-in policy's
action mode), and runs one episode with :func:`training.evaluation.harness.evaluate`
(the one episode runner, :func:`training.evaluation.episode.run_episode`). The row is
the episode's :meth:`~training.evaluation.episode.EpisodeResult.row` (distances in m,
angles in deg, times in s) under the cell's scenario, policy and seed.

:func:`run_cells` runs a few cells; it is what a process-pool worker or a Ray task
executes, so it takes and returns plain picklable data only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from training.evaluation.harness import evaluate
from training.evaluation.policies import POLICY_ACTION_MODES, builtin_name, load_policy, overrides_beside_policy
from training.sweep.spec import Cell

__all__ = ["run_cell", "run_cells", "CELL_KEYS"]

#: The columns that name a cell, first in every row.
CELL_KEYS = ("scenario", "policy", "seed")


def run_cell(cell: Cell, options: Mapping[str, Any]) -> dict[str, Any]:
    """One episode of ``cell``; its table row (the cell's keys, then the episode's columns).

    Args:
        cell: the scenario, policy spec and reset seed.
        options: ``random_scenarios``, ``max_cycles``, ``sample_actions`` (a trained policy
            samples) and ``overrides`` (configuration fields);
            :attr:`training.sweep.spec.SweepSpec.options`.

    Raises:
        PolicyLoadError: the policy spec names no loadable policy.
        ConfigError: a bad scenario or option.
    """
    builtin = builtin_name(cell.policy)
    sample = bool(options.get("sample_actions", False)) and builtin is None
    policy = load_policy(cell.policy, cell.scenario, cell.seed, sample_actions=sample)
    env_options = dict(getattr(policy, "env_options", {}))  # a trained policy says which env it fits
    action_mode = env_options.pop("action_mode", None) or POLICY_ACTION_MODES.get(builtin or "", "switching")
    overrides = overrides_beside_policy(cell.policy, env_options, options.get("overrides", {}))
    result = evaluate(
        cell.scenario,
        policy,
        1,
        cell.seed,
        random_scenarios=bool(options["random_scenarios"]),
        action_mode=action_mode,
        max_cycles=options["max_cycles"],
        **env_options,
        **overrides,
    )
    episode = result.episodes[0].row()
    del episode["episode"], episode["seed"]
    return {"scenario": cell.scenario, "policy": cell.policy, "seed": cell.seed, **episode}


def run_cells(cells: Sequence[Cell], options: Mapping[str, Any]) -> list[dict[str, Any]]:
    """:func:`run_cell` of every cell, in order."""
    return [run_cell(cell, options) for cell in cells]
