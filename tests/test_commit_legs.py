"""``commit_legs``: in switching mode a leg once started runs to its end; ``hold`` is
ignored and masked for a robot driving a leg on a localised estimate."""

from __future__ import annotations

import pytest

from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env


def _drive_then_hold(commit_legs: bool):
    """ugv_0 advances for 3 steps, then every robot holds; the events and ugv_0's masks."""
    env = parallel_env("top_observer", observer_agent=False, action_masks=True, commit_legs=commit_legs, max_cycles=600)
    env.reset(seed=0)
    events, masks = [], []
    for t in range(600):
        action = {"ugv_0": 1 if t < 3 else 0, "ugv_1": 0}
        _, _, terminations, truncations, infos = env.step(action)
        events += [(t, ev) for ev in infos["ugv_0"]["events"] if ev.endswith("ugv_0")]
        masks.append(infos["ugv_0"]["action_mask"].tolist())
        if any(ev.startswith(("leg_done", "static", "leg_blocked")) for _, ev in events):
            break
        assert not any(terminations.values()) and not any(truncations.values())
    return env, events, masks


def test_hold_stops_a_leg_without_commit_legs():
    env, events, _ = _drive_then_hold(commit_legs=False)
    assert [ev for _, ev in events] == ["mobile:ugv_0", "static:ugv_0"]
    assert events[-1][0] == 3  # at the first hold


def test_a_committed_leg_runs_to_its_end_and_hold_is_masked():
    env, events, masks = _drive_then_hold(commit_legs=True)
    assert [ev for _, ev in events] == ["mobile:ugv_0", "leg_done:ugv_0"]
    done = events[-1][0]
    assert done > 10  # it drove on through the holds
    assert masks[0] == [0, 1]  # on its way: only advance (hold would be ignored)
    assert masks[done] == [1, 0]  # static again: hold, and no advance during the dwell
    assert env.world.is_static("ugv_0")


def test_commit_legs_needs_the_switching_mode():
    with pytest.raises(ConfigError, match=r"env\.commit_legs"):
        parallel_env("top_observer", action_mode="velocity", commit_legs=True)
    with pytest.raises(ConfigError, match=r"env\.commit_legs"):
        parallel_env("top_observer", commit_legs="yes")
