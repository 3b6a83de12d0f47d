"""The built-in policy specs of ``moma-env evaluate --policy``, without heavy imports.

What a spec names is decided here, so that the command line (``--pretrain``), the
training configuration and :func:`training.evaluation.policies.load_policy` read a
spec alike: a built-in name (:data:`BUILTIN_POLICIES`), or ``NAME@L`` for a built-in
policy that takes a leg length (:data:`LEG_POLICIES`: ``greedy@1.5`` starts every leg
with 1.5 m on an env with ``leg_lengths``); anything else is a path or a published
policy's name.
"""

from __future__ import annotations

import math

__all__ = ["BUILTIN_POLICIES", "POLICY_ACTION_MODES", "LEG_POLICIES", "builtin_name", "leg_spec"]

#: Policy specs that name a built-in policy rather than a file.
BUILTIN_POLICIES = (
    "scripted", "greedy", "pipeline", "rollout", "rollout_nowait", "pipeline_rollout", "pipeline_rollout_masks", "planned", "servo",
    "random",
)

#: The action mode each built-in policy acts in.
POLICY_ACTION_MODES = {
    "scripted": "switching", "greedy": "switching", "pipeline": "switching", "rollout": "switching", "rollout_nowait": "switching",
    "pipeline_rollout": "switching", "pipeline_rollout_masks": "switching", "planned": "velocity", "servo": "velocity", "random": "switching",
}

#: The built-in policies that take a leg length after ``@``: ``greedy@L`` starts every leg
#: with ``L`` m; ``rollout@L`` is the lookahead over the starts and every leg length, with
#: ``greedy@L`` as its base; ``rollout_nowait@L`` the same lookahead without the choice of
#: starting no robot where one may start.
LEG_POLICIES = ("greedy", "rollout", "rollout_nowait")


def leg_spec(spec: str) -> tuple[str, float] | None:
    """``(name, leg m)`` of a spec ``NAME@L`` whose name takes a leg length, else None.

    Raises:
        ValueError: such a name with a length that is not a positive finite number of metres.
    """
    name, sep, text = spec.partition("@")
    if not sep or name not in LEG_POLICIES:
        return None
    try:
        leg_m = float(text)
    except ValueError:
        leg_m = math.nan
    if not 0.0 < leg_m < math.inf:
        raise ValueError(f"policy {spec!r}: the leg length after '@' must be a positive number of metres, got {text!r}")
    return name, leg_m


def builtin_name(spec: str) -> str | None:
    """The built-in policy a spec names (``"greedy"`` for ``"greedy"`` and ``"greedy@1.5"``), else None."""
    if spec in BUILTIN_POLICIES:
        return spec
    name, sep, _ = spec.partition("@")
    return name if sep and name in LEG_POLICIES else None
