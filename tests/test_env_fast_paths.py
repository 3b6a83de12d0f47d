"""The env's fast paths against the code they replaced (kept here as the reference), on
random inputs, equal bit for bit: the action masks from templates, the device table, the
UGV observations with their kept kernel inputs, the tracking controller's sums, the
Discrete parse's shortcut, and the reward's weights read once per weights object."""

from __future__ import annotations

import math
from dataclasses import replace
from numbers import Integral
from types import SimpleNamespace

import numpy as np
import pytest
from gymnasium import spaces

from moma_env.control.tracking import BoardTrackingController
from moma_env.env.actions import SwitchingActions, parse_discrete
from moma_env.env.observations import _ONE_HOT, DEVICE_COLUMNS, ObservationLayout, _ugv_rows, device_table
from moma_env.estimator import Status
from moma_env.estimator.results import Phase, RobotEstimate

# ---------------------------------------------------------------- references (the replaced code)


def reference_mask(mode: SwitchingActions, agent: str, simulation, references) -> np.ndarray:
    mask = np.ones(mode.n_actions(agent), dtype=np.int8)
    if agent in mode.committed:
        mask[:] = 0
        mask[mode.ADVANCE] = 1
        return mask
    mobile = simulation.mobile
    check = simulation.check_mobile
    if agent not in mobile:
        mask[mode.ADVANCE : mode.ADVANCE + mode.n_advances] = check(agent, mobile, references) is None
    sled = mode.tows.get(agent)
    if sled is not None and sled not in mobile:
        reel = mode.reel
        if agent not in mobile:
            mask[reel] = check(sled, mobile, references) is None
        elif simulation.rules is None or simulation.rules.dwell_s <= 0.0:
            mask[reel] = check(sled, mobile - {agent}, references) is None
        else:
            mask[reel] = 0
    return mask


def reference_device_table(frame, devices, board_device, camera_owner, lost_after_s) -> np.ndarray:
    seen: set[str] = set()
    for d in frame.detections:
        seen.add(board_device(d.board_id))
        seen.add(camera_owner[d.camera_id])
    t = frame.time
    mobile = frame.mobile
    values: list[float] = []
    for device in devices:
        e = frame.estimates[device]
        status = e.status
        pose = None if status is Status.LOST else frame.estimated[device]
        values += (0.0, 0.0, 0.0, 0.0) if pose is None else (*pose, 1.0)
        values.append(0.0 if device in mobile else 1.0)
        values += _ONE_HOT[status]
        values.append(1.0 if e.last_fresh_time is None else min(1.0, (t - e.last_fresh_time) / lost_after_s))
        values += (e.position_std_m, e.heading_std_rad, 1.0 if device in seen else 0.0)
    return np.array(values, dtype=np.float64).reshape(len(devices), len(DEVICE_COLUMNS))


def reference_ugvs(layout: ObservationLayout, table, since_switch, dwell_remaining, ropes) -> dict[str, np.ndarray]:
    agents = layout._ugv_agents
    rope = np.zeros(len(agents))
    if ropes:
        for u, agent in enumerate(agents):
            value = ropes.get(agent)
            if value is not None:
                rope[u] = value
    scalars = np.array((layout._cx, layout._cy, layout._r, since_switch, layout._switch_horizon, dwell_remaining, layout._dwell))
    out = np.empty(layout._low.shape, dtype=np.float32)
    _ugv_rows(table, layout._rows, layout._goals, rope, scalars, layout._low, layout._high, layout._sizes, out)
    sizes = layout._sizes
    width = out.shape[1]
    return {a: out[u] if sizes[u] == width else out[u, : sizes[u]] for u, a in enumerate(agents)}


def reference_tracking_command(controller: BoardTrackingController, board_positions_c) -> np.ndarray:
    c = controller.config
    if len(board_positions_c) == 0:
        return np.array([0.0, 0.0, 0.0, c.search_climb])
    points = [(float(p[0]), float(p[1]), float(p[2])) for p in board_positions_c]
    n = len(points)
    cx = sum(p[0] for p in points) / n
    cy = sum(p[1] for p in points) / n
    cz = sum(p[2] for p in points) / n
    spread = 2.0 * max(math.hypot(p[0] - cx, p[1] - cy) for p in points)
    R = controller._R_b_c_rows
    vx = c.gain * (R[0][0] * cx + R[0][1] * cy)
    vy = c.gain * (R[1][0] * cx + R[1][1] * cy)
    if controller._offset is not None:
        vx -= c.gain * controller._offset[0]
        vy -= c.gain * controller._offset[1]
    speed = math.hypot(vx, vy)
    if speed > c.max_speed:
        vx *= c.max_speed / speed
        vy *= c.max_speed / speed
    depth_error = cz - controller.target_depth(spread)
    climb = min(c.max_climb, max(-c.max_climb, -c.altitude_gain * depth_error))
    return np.array([vx, vy, 0.0, climb])


def reference_parse_discrete(agent, action, space) -> int:
    value = action
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "iu":
        value = value.reshape(()).item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Integral) or not 0 <= int(value) < space.n:
        raise ValueError(f"action of {agent!r} must be an integer in [0, {space.n}) (the space {space}), got {action!r}")
    return int(value)


# ---------------------------------------------------------------- stand-ins


class FakeSimulation:
    """What the masks read of a simulation: the mobile devices, the rules' answer (random
    but fixed per question), the reference sets and the dwell."""

    def __init__(self, rng: np.random.Generator, devices: list[str], dwell_s: float | None):
        self._mobile = {d for d in devices if rng.random() < 0.4}
        self._answers: dict = {}
        self._rng = rng
        self.rules = None if dwell_s is None else SimpleNamespace(dwell_s=dwell_s)

    @property
    def mobile(self) -> frozenset[str]:
        return frozenset(self._mobile)

    def reference_devices(self):
        return set(), set()

    def check_mobile(self, device, mobile=None, references=None):
        key = (device, frozenset(self._mobile if mobile is None else mobile))
        if key not in self._answers:
            self._answers[key] = None if self._rng.random() < 0.5 else "dwell"
        return self._answers[key]


@pytest.mark.parametrize("leg_lengths", [None, (0.2, 0.5, 1.0)])
@pytest.mark.parametrize("commit_legs", [False, True])
def test_masks_match_the_reference(leg_lengths, commit_legs):
    rng = np.random.default_rng(7)
    ugvs = ["ugv_0", "ugv_1", "ugv_2"]
    tows = {"ugv_1": "sled_0"}
    mode = SwitchingActions(tows, {u: (0.3, 1.0) for u in ugvs}, commit_legs=commit_legs, leg_lengths=leg_lengths)
    for _ in range(300):
        dwell = [None, 0.0, 1.0][rng.integers(3)]
        sim = FakeSimulation(rng, ugvs + ["sled_0"], dwell)
        mode.committed = {u for u in ugvs if commit_legs and rng.random() < 0.3}
        refs = sim.reference_devices()
        got = mode.masks(ugvs, sim)
        for agent in ugvs:
            want = reference_mask(mode, agent, sim, refs)
            assert got[agent].dtype == want.dtype and np.array_equal(got[agent], want)
            single = mode.mask(agent, sim, refs)
            assert np.array_equal(single, want)
        # Every call returns new arrays: changing one changes no later mask.
        for agent in ugvs:
            got[agent][:] = 7
        again = mode.masks(ugvs, sim)
        for agent in ugvs:
            assert np.array_equal(again[agent], reference_mask(mode, agent, sim, refs))


def _estimate(rng: np.random.Generator, name: str) -> RobotEstimate:
    status = list(Status)[rng.integers(len(Status))]
    has_cov = rng.random() < 0.8
    cov = None
    if has_cov:
        a = rng.normal(size=(6, 6)) * 0.05
        cov = a @ a.T
    fresh = None if rng.random() < 0.2 else float(rng.uniform(0, 10))
    return RobotEstimate(name, np.eye(4), status, Phase.MOBILE, fresh, 0, cov)


def test_device_table_matches_the_reference():
    rng = np.random.default_rng(3)
    devices = ["ugv_0", "ugv_1", "ugv_2", "sled_0"]
    board_owner = {i: d for i, d in enumerate(devices)}
    camera_owner = {"cam_0": "ugv_0", "cam_1": "ugv_2", "uav_cam": "uav"}
    for _ in range(300):
        detections = tuple(
            SimpleNamespace(board_id=int(rng.integers(len(devices))), camera_id=list(camera_owner)[rng.integers(3)])
            for _ in range(rng.integers(0, 6))
        )
        estimated = {d: (None if rng.random() < 0.2 else tuple(rng.normal(size=3).tolist())) for d in devices}
        frame = SimpleNamespace(
            detections=detections,
            time=float(rng.uniform(0, 12)),
            mobile=frozenset(d for d in devices if rng.random() < 0.5),
            estimates={d: _estimate(rng, d) for d in devices},
            estimated=estimated,
        )
        lost_after = float(rng.uniform(0.5, 3.0))
        got = device_table(frame, devices, board_owner.__getitem__, camera_owner, lost_after)
        want = reference_device_table(frame, devices, board_owner.__getitem__, camera_owner, lost_after)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got, want, equal_nan=True)


def test_ugv_observations_match_the_reference():
    rng = np.random.default_rng(5)
    devices = ("ugv_0", "ugv_1", "ugv_2", "sled_0")
    ugvs = ("ugv_0", "ugv_1", "ugv_2")
    goals = {"ugv_0": (1.0, 2.0, 0.5), "ugv_2": (-1.0, 0.5, -2.0)}
    layout = ObservationLayout(devices, ugvs, {"ugv_1": "sled_0"}, (), (0.5, -0.2), 3.0, 1.0, 5.0, goals=goals)
    for _ in range(300):
        table = rng.normal(size=(len(devices), len(DEVICE_COLUMNS)))
        table[:, 3:8] = rng.integers(0, 2, size=(len(devices), 5))
        table[rng.random(table.shape) < 0.05] = np.nan
        ropes = [None, {}, {"ugv_1": float(rng.uniform(0, 1))}, {"ugv_0": 0.3}][rng.integers(4)]
        since, dwell_left = float(rng.uniform(0, 8)), float(rng.uniform(0, 2))
        got = layout.ugvs(table, since, dwell_left, ropes)
        want = reference_ugvs(layout, table, since, dwell_left, ropes)
        assert list(got) == list(want)
        for agent in ugvs:
            assert got[agent].dtype == want[agent].dtype and got[agent].shape == want[agent].shape
            assert np.array_equal(got[agent], want[agent], equal_nan=True)


@pytest.mark.parametrize("offset", [(0.0, 0.0), (0.4, -0.3)])
def test_tracking_command_matches_the_reference(offset):
    from moma_env.control.tracking import TrackingControllerConfig

    rng = np.random.default_rng(11)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    controller = BoardTrackingController(R, 420.0, (640, 480), TrackingControllerConfig(target_offset=offset))
    for _ in range(2000):
        points = [rng.normal(scale=[1.0, 1.0, 2.0]).tolist() for _ in range(rng.integers(0, 9))]
        if rng.random() < 0.3:
            points = [np.array(p) for p in points]
        got = controller.command(points)
        want = reference_tracking_command(controller, points)
        assert got.dtype == want.dtype and np.array_equal(got, want)


def test_parse_discrete_matches_the_reference():
    space = spaces.Discrete(3)
    values = [0, 1, 2, 3, -1, True, False, 1.0, "1", None, np.int64(2), np.uint8(1), np.int32(5), np.bool_(True),
              np.array(1), np.array([2]), np.array([[0]]), np.array([1, 2]), np.array(1.0), 2**70]
    for value in values:
        try:
            want = ("ok", reference_parse_discrete("ugv_0", value, space))
        except ValueError as error:
            want = ("error", str(error))
        try:
            got = ("ok", parse_discrete("ugv_0", value, space))
        except ValueError as error:
            got = ("error", str(error))
        assert got == want and type(got[1]) is type(want[1])


def test_reward_weights_replaced_are_read():
    from moma_env.env.factory import parallel_env

    env = parallel_env("top_observer", action_mode="switching")
    env.reset(seed=0)
    _, _, _, _, infos = env.step({a: 0 for a in env.agents if a.startswith("ugv")})
    weights = env._reward.weights
    env._reward.weights = replace(weights, time=weights.time * 3.0 - 1.0)
    _, _, _, _, infos = env.step({a: 0 for a in env.agents if a.startswith("ugv")})
    assert infos["ugv_0"]["reward_terms"]["time"] == (weights.time * 3.0 - 1.0) * 1.0


def test_batch_stacking_matches_np_stack():
    from moma_env.vector.env import _stack

    rng = np.random.default_rng(2)
    for _ in range(200):
        n = int(rng.integers(1, 40))
        shape = tuple(int(k) for k in rng.integers(1, 6, size=rng.integers(1, 4)))
        dtype = [np.float32, np.float64, np.int8, np.uint8, bool][rng.integers(5)]
        rows = [rng.normal(size=shape).astype(dtype) for _ in range(n)]
        if rng.random() < 0.3:  # rows of one array, as a copy's views of its kernel output are
            rows = list(np.ascontiguousarray(rng.normal(size=(n, *shape)).astype(dtype)))
        got, want = _stack(rows), np.stack(rows)
        assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want)
        dicts = [{"vector": r, "image": r.astype(np.uint8)} for r in rows]
        got_dict = _stack(dicts)
        assert list(got_dict) == ["vector", "image"]
        for key in got_dict:
            want_key = np.stack([d[key] for d in dicts])
            assert got_dict[key].dtype == want_key.dtype and np.array_equal(got_dict[key], want_key)
    with pytest.raises(ValueError):
        _stack([np.zeros(3), np.zeros(4)])
