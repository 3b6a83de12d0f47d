"""The UGVs' observations, built in one compiled call, against the per-agent Python
builder they replace (kept here as the reference), bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.env.observations import DEVICE_COLUMNS, STATUS_ORDER, ObservationLayout, uncertainty

COLUMN = {name: i for i, name in enumerate(DEVICE_COLUMNS)}


def reference_ugv(layout: ObservationLayout, agent, table, goal, since, dwell_left, rope) -> np.ndarray:
    """The Python builder of one UGV's observation, as it was (lists of floats, then float32 and clip)."""
    rows = {d: table[i] for i, d in enumerate(layout.devices)}

    def pose_of(row):
        return (float(row[0]), float(row[1]), float(row[2])) if row[COLUMN["has_pose"]] else None

    me = rows[agent]
    pose = pose_of(me)
    cx, cy, r = layout._cx, layout._cy, layout._r
    out: list[float] = []
    if pose is None:
        out += [0.0] * 5
    else:
        x, y, yaw = pose
        out += [(x - cx) / r, (y - cy) / r, math.cos(yaw), math.sin(yaw), 1.0]
    out.append(float(me[COLUMN["static"]]))
    out += [float(me[COLUMN[s.name.lower()]]) for s in STATUS_ORDER]
    out.append(float(me[COLUMN["staleness"]]))
    out += uncertainty(float(me[COLUMN["position_std_m"]]), float(me[COLUMN["heading_std_rad"]]))
    two_r = 2.0 * r
    if pose is not None:
        c, s = math.cos(yaw), math.sin(yaw)
    if goal is not None and pose is not None:
        dx, dy, dyaw = goal[0] - x, goal[1] - y, goal[2] - yaw
        out += [(c * dx + s * dy) / two_r, (-s * dx + c * dy) / two_r, math.cos(dyaw), math.sin(dyaw), math.hypot(dx, dy) / two_r, 1.0]
    else:
        out += [0.0, 0.0, 0.0, 0.0, 0.0, 1.0 if goal is not None else 0.0]
    out.append(min(1.0, since / layout._switch_horizon))
    out.append(0.0 if layout._dwell <= 0 else min(1.0, dwell_left / layout._dwell))
    out.append(float(me[COLUMN["seen"]]))
    for other in layout.devices:
        if other == agent:
            continue
        o = rows[other]
        other_pose = pose_of(o)
        if other_pose is not None and pose is not None:
            dx, dy, dyaw = other_pose[0] - x, other_pose[1] - y, other_pose[2] - yaw
            out += [(c * dx + s * dy) / two_r, (-s * dx + c * dy) / two_r, math.cos(dyaw), math.sin(dyaw), 1.0]
        else:
            out += [0.0] * 5
        out.append(float(o[COLUMN["static"]]))
        out += [float(o[COLUMN[s.name.lower()]]) for s in STATUS_ORDER]
    if agent in layout.tows:
        out.append(0.0 if rope is None else rope)
    low, high = layout.spaces[agent].low, layout.spaces[agent].high
    return np.array(out, dtype=np.float32).clip(low, high)


def random_table(rng: np.random.Generator, n: int) -> np.ndarray:
    """Device rows of every kind: no pose, LOST, NaN or huge deviations, poses outside the
    arena (clipped features), exact zeros (signed), stale and fresh."""
    table = np.zeros((n, len(DEVICE_COLUMNS)))
    for i in range(n):
        status = rng.integers(3)
        has_pose = status != 2 and rng.random() < 0.9
        if has_pose:
            table[i, :3] = rng.choice([rng.normal(0.0, 3.0, 3), np.array([0.0, -0.0, -0.0]), rng.normal(0.0, 30.0, 3)], p=[0.8, 0.1, 0.1])
            table[i, COLUMN["has_pose"]] = 1.0
        table[i, COLUMN["static"]] = float(rng.random() < 0.5)
        table[i, COLUMN["localised"] + status] = 1.0
        table[i, COLUMN["staleness"]] = rng.choice([1.0, rng.random(), 0.0])
        table[i, COLUMN["position_std_m"]] = rng.choice([math.nan, rng.exponential(0.05), 5.0])
        table[i, COLUMN["heading_std_rad"]] = rng.choice([math.nan, rng.exponential(0.05), 0.0])
        table[i, COLUMN["seen"]] = float(rng.random() < 0.5)
    return table


@pytest.mark.parametrize("seed", range(4))
def test_every_ugv_observation_is_the_python_builders_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    ugvs = [f"ugv_{k}" for k in range(2 + seed)]
    sleds = ["sled_0"] if seed % 2 else []
    tows = {"ugv_0": "sled_0"} if sleds else {}
    goals = {a: tuple(rng.normal(0.0, 2.0, 3)) for a in ugvs if rng.random() < 0.8}
    dwell = [0.0, 0.5, 1.0][seed % 3]
    layout = ObservationLayout(ugvs + sleds, ugvs, tows, (), (0.5, -0.25), 2.5, dwell, 5.0, goals=goals)
    for _ in range(300):
        table = random_table(rng, len(ugvs) + len(sleds))
        since, dwell_left = rng.choice([0.0, -0.0, rng.uniform(0.0, 8.0)]), rng.choice([-0.0, rng.uniform(0.0, 1.2)])
        ropes = {"ugv_0": rng.uniform(0.0, 1.5)} if tows else None
        got = layout.ugvs(table, since, dwell_left, ropes)
        assert list(got) == ugvs
        for agent in ugvs:
            rope = None if ropes is None else ropes.get(agent)
            want = reference_ugv(layout, agent, table, goals.get(agent), since, dwell_left, rope)
            assert got[agent].dtype == np.float32 and got[agent].shape == layout.spaces[agent].shape
            assert got[agent].tobytes() == want.tobytes(), agent


def test_a_layout_keeps_the_previous_episodes_features_and_spaces_for_the_same_agents():
    devices, ugvs = ("ugv_0", "ugv_1", "sled_0"), ("ugv_0", "ugv_1")
    tows = {"ugv_1": "sled_0"}
    first = ObservationLayout(devices, ugvs, tows, ("observer",), (0.0, 0.0), 2.0, 1.0, 5.0, goals={"ugv_0": (1.0, 0.0, 0.0)})
    same = ObservationLayout(devices, ugvs, tows, ("observer",), (3.0, 1.0), 4.0, 2.0, 6.0, previous=first)
    assert same.spaces is first.spaces and same.features is first.features
    assert (same._cx, same._r, same._dwell) == (3.0, 4.0, 2.0)  # the episode's own values
    fresh = ObservationLayout(devices, ugvs, tows, ("observer",), (3.0, 1.0), 4.0, 2.0, 6.0)
    assert fresh.features == same.features and all(fresh.spaces[a] == same.spaces[a] for a in fresh.spaces)
    for changed in (
        ObservationLayout(devices, ugvs, {}, ("observer",), (0.0, 0.0), 2.0, 1.0, 5.0, previous=first),
        ObservationLayout(devices, ugvs, tows, (), (0.0, 0.0), 2.0, 1.0, 5.0, previous=first),
        ObservationLayout(("ugv_0", "ugv_1"), ugvs, {}, (), (0.0, 0.0), 2.0, 1.0, 5.0, previous=first),
    ):
        assert changed.spaces is not first.spaces
        assert changed.features == ObservationLayout(changed.devices, ugvs, changed.tows, tuple(a for a in changed.features if a not in ugvs),
                                                     (0.0, 0.0), 2.0, 1.0, 5.0).features

