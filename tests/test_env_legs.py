"""Legs of the switching mode: a leg ends at its end (``leg_done``) or, when the robot is
blocked and comes no closer for a second, where it stands (``leg_blocked``)."""

from __future__ import annotations

import math

import numpy as np

from moma_env.env.factory import parallel_env

#: A random top_observer layout whose ugv_0 drives straight into the static ugv_1 on its first leg.
BLOCKED_SEED = 10002


def _run(env, actions_of, steps, until=None):
    """Step ``env`` with ``actions_of(t)`` for at most ``steps`` (or through the step that
    reports the event ``until``); every (t, agent, event)."""
    events = []
    for t in range(steps):
        if not env.agents:
            break
        _, _, _, _, infos = env.step(actions_of(t))
        new = [(t, agent, ev) for agent in infos for ev in infos[agent]["events"]]
        events += new
        if until is not None and any(ev == until for _, _, ev in new):
            break
    return events


def test_a_robot_blocked_by_a_static_robot_stops_and_is_declared_static():
    env = parallel_env("top_observer", random_scenarios=True, observer_agent=False, max_cycles=400)
    env.reset(seed=BLOCKED_SEED)
    world = env.world
    # The layout's premise: ugv_1 sits within two robot radii of ugv_0's straight path to its goal.
    start, other = np.array(world.ugv_pose("ugv_0")[:2]), np.array(world.ugv_pose("ugv_1")[:2])
    goal = np.array(env.scenario.goals["ugv_0"][:2])
    along = (goal - start) / np.linalg.norm(goal - start)
    offset = other - start
    lateral = abs(offset[0] * along[1] - offset[1] * along[0])
    radius = env.scenario.world.ugv("ugv_0").radius
    assert 0.0 < float(offset @ along) < env.scenario.leg_length and lateral < 2.0 * radius

    events = _run(env, lambda t: {"ugv_0": 1, "ugv_1": 0}, 400, until="leg_blocked:ugv_0")
    names = [(agent, ev) for _, agent, ev in events]
    assert ("ugv_0", "mobile:ugv_0") in names
    blocked = [t for t, agent, ev in events if ev == "leg_blocked:ugv_0"]
    assert blocked and ("ugv_0", "leg_done:ugv_0") not in names[: names.index(("ugv_0", "leg_blocked:ugv_0"))]
    assert world.is_static("ugv_0")
    # It stopped against ugv_1, short of the leg's end: the robots touch.
    gap = math.dist(world.ugv_pose("ugv_0")[:2], world.ugv_pose("ugv_1")[:2])
    assert gap < 2.0 * radius + 0.01
    # Blocked after the stall time, not at once: it drove first, then pushed for a second.
    assert world.time > 1.0 and math.dist(world.ugv_pose("ugv_0")[:2], start) > 0.1
    # Once ugv_1 has moved on, ugv_0's next advance is granted again.
    later = _run(env, lambda t: {"ugv_0": 0, "ugv_1": 1}, 400)
    assert any(ev == "mobile:ugv_1" for _, _, ev in later)


def test_free_legs_end_at_their_end():
    # The default layout: each robot advances in turn and its legs end as leg_done, never blocked.
    env = parallel_env("top_observer", observer_agent=False, max_cycles=600)
    env.reset(seed=0)
    events = _run(env, lambda t: {"ugv_0": 1 if (t // 150) % 2 == 0 else 0, "ugv_1": 0 if (t // 150) % 2 == 0 else 1}, 600)
    done = [ev for _, _, ev in events if ev.startswith("leg_done")]
    assert len(done) >= 2
    assert not any(ev.startswith("leg_blocked") for _, _, ev in events)
