"""MOMA estimator: configuration, bad input, the outlier gate, declarations, properties."""

from __future__ import annotations

import ast
import math
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env import geometry as g
from moma_env.config import ConfigError
from moma_env.estimator import (
    EVENT_KINDS,
    Detection,
    EstimatorConfig,
    MomaEstimator,
    OutlierGate,
    OutlierGateConfig,
    Phase,
    Status,
    SwitchWindow,
    UnknownBoardError,
    UnknownCameraError,
    UnknownRobotError,
)

DT = 0.04
BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.0, 0.0, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, -0.05])
NO_CORNERS = np.empty((0, 2))
T_A = g.se2_to_se3(0.0, 0.0, 0.2)
T_B = g.se2_to_se3(0.6, 0.1, -0.4)
T_W_C = g.make_transform(g.rot_z(0.3) @ g.rot_x(0.05), [0.3, 0.0, 2.0]) @ CAM_DOWN


def detection(board_id: int, T_w_b: np.ndarray, t: float, *, camera: str = "down", T_w_c: np.ndarray = T_W_C,
              mount: np.ndarray = BOARD_TOP) -> Detection:
    return Detection(camera, board_id, g.invert(T_w_c) @ T_w_b @ mount, NO_CORNERS, (), t)


def top_observer(config: EstimatorConfig | None = None, *, b_static: bool = False, b_pose: bool = True) -> MomaEstimator:
    """a: reference; b: board 1, mobile (or static) with (or without) an initial pose; uav: camera."""
    est = MomaEstimator(config)
    est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_A)
    est.add_robot("b", boards={1: BOARD_TOP}, static=b_static, initial_pose=T_B if b_pose else None)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    return est


# --------------------------------------------------------------------------- package hygiene
#: The package's base modules the estimator may import.
BASE_MODULES = ("moma_env.geometry", "moma_env.config", "moma_env.records")


def imported_names(path: pathlib.Path) -> list[str]:
    """Every module name ``path`` imports (``import a.b``: ``a.b``; ``from a.b import c``: ``a.b``)."""
    names: list[str] = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.extend(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.append(node.module or "")
    return names


def test_the_records_module_imports_only_the_standard_library():
    path = pathlib.Path(__file__).resolve().parents[1] / "moma_env" / "records.py"
    for name in imported_names(path):
        assert name.split(".")[0] in {"__future__", "dataclasses", "typing"}, name


def test_estimator_imports_only_stdlib_numpy_and_the_base_modules():
    """numpy, the standard library, and of the package only its base modules (geometry,
    config, records), none of which imports the simulator."""
    allowed_roots = {"numpy", "moma_env"}
    package = pathlib.Path(__file__).resolve().parents[1] / "moma_env" / "estimator"
    for path in package.glob("*.py"):
        for name in imported_names(path):
            root = name.split(".")[0]
            if root in allowed_roots:
                assert name in {"numpy", *BASE_MODULES} or name.startswith("moma_env.estimator"), (
                    path.name,
                    name,
                )
            elif path.name == "graph.py" and root == "gtsam":
                continue  # the pose graph's optional dependency (the ``graph`` extra), nothing else may use it
            else:
                # numba: the compiled kernels (a core dependency, as numpy); json and os: the detection log's file
                assert root in {"__future__", "math", "enum", "dataclasses", "collections", "typing", "numba", "json", "os"}, (path.name, name)


# --------------------------------------------------------------------------- configuration
@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"window": 0}, "estimator.window"),
        ({"window": 2.5}, "estimator.window"),
        ({"window": True}, "estimator.window"),
        ({"lost_after_s": 0.0}, "estimator.lost_after_s"),
        ({"lost_after_s": float("nan")}, "estimator.lost_after_s"),
        ({"settle_delay_s": -0.1}, "estimator.settle_delay_s"),
        ({"settle_delay_s": "1"}, "estimator.settle_delay_s"),
        ({"gate": "on"}, "estimator.gate"),
    ],
)
def test_bad_estimator_config_names_the_field(kwargs, field):
    with pytest.raises(ConfigError) as info:
        EstimatorConfig(**kwargs)
    assert info.value.field == field
    assert str(info.value).startswith(field + ":")
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"start_samples": 0}, "estimator.gate.start_samples"),
        ({"start_tolerance_m": 0.0}, "estimator.gate.start_tolerance_m"),
        ({"history": 1.5}, "estimator.gate.history"),
        ({"jump_tolerance_m": -0.15}, "estimator.gate.jump_tolerance_m"),
        ({"reset_after_s": float("inf")}, "estimator.gate.reset_after_s"),
        ({"enabled": 1}, "estimator.gate.enabled"),
    ],
)
def test_bad_gate_config_names_the_field(kwargs, field):
    with pytest.raises(ConfigError) as info:
        OutlierGateConfig(**kwargs)
    assert info.value.field == field


def test_config_defaults_follow_the_authors():
    cfg = EstimatorConfig()
    assert (cfg.window, cfg.lost_after_s, cfg.settle_delay_s) == (25, 2.0, 0.0)
    assert cfg.gate == OutlierGateConfig(True, 3, 0.04, 3, 0.15, 1.0)
    assert cfg.gate_enabled
    assert not EstimatorConfig(gate=None).gate_enabled
    assert not EstimatorConfig(gate=OutlierGateConfig(enabled=False)).gate_enabled
    with pytest.raises(TypeError, match="EstimatorConfig"):
        MomaEstimator({"window": 3})  # type: ignore[arg-type]


# --------------------------------------------------------------------------- bad declarations
def test_duplicate_names_and_ids_are_rejected():
    est = top_observer()
    with pytest.raises(ConfigError, match="duplicate robot name 'a'"):
        est.add_robot("a", static=False)
    with pytest.raises(ConfigError, match="duplicate board id 1 .*robot 'b'"):
        est.add_robot("c", boards={1: BOARD_TOP}, static=False)
    with pytest.raises(ConfigError, match="duplicate camera id 'down' .*robot 'uav'"):
        est.add_robot("c", cameras={"down": CAM_DOWN}, static=False)
    assert est.robots == ("a", "b", "uav")  # nothing half-added
    est.add_robot("c", boards={5: BOARD_TOP}, static=False)  # the failed attempts left no trace
    assert est.robots == ("a", "b", "uav", "c")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"boards": {0.5: BOARD_TOP}}, "board ids must be integers"),
        ({"boards": {2: np.eye(3)}}, r"boards\[2\]: must be a 4x4"),
        ({"boards": {2: np.full((4, 4), np.nan)}}, r"boards\[2\]: must be finite"),
        ({"boards": {2: 2.0 * np.eye(4)}}, r"boards\[2\]: last row must be"),
        ({"boards": [BOARD_TOP]}, "must be a mapping"),
        ({"cameras": {"": CAM_DOWN}}, "camera ids must be non-empty strings"),
        ({"cameras": {"cam": "eye"}}, r"cameras\['cam'\]: must be a 4x4 array"),
        ({"initial_pose": g.make_transform(np.diag([1.0, 1.0, -1.0]))}, "initial_pose: rotation block must be a proper rotation"),
        ({"static": 1}, "static: must be a bool"),
    ],
)
def test_bad_robot_declarations_name_the_problem(kwargs, match):
    est = MomaEstimator()
    kwargs = {"static": False} | kwargs
    with pytest.raises(ConfigError, match=match):
        est.add_robot("r", **kwargs)
    with pytest.raises(ConfigError, match="name"):
        est.add_robot("", static=False)


def test_unknown_ids_raise_naming_the_id():
    est = top_observer()
    with pytest.raises(UnknownBoardError, match="unknown board id 9") as info:
        est.update(0.04, [detection(9, T_B, 0.04)])
    assert isinstance(info.value, KeyError) and info.value.key == 9
    with pytest.raises(UnknownCameraError, match="unknown camera id 'side'"):
        est.update(0.04, [detection(0, T_A, 0.04, camera="side")])
    with pytest.raises(UnknownCameraError, match="'side'"):
        est.camera_pose("side")
    with pytest.raises(UnknownRobotError, match="unknown robot 'zed'"):
        est.estimate("zed")
    with pytest.raises(UnknownRobotError, match="'zed'"):
        est.set_static("zed", True, 0.0)


def test_bad_detection_and_time_raise_before_changing_state():
    est = top_observer()
    est.update(0.04, [detection(0, T_A, 0.04), detection(1, T_B, 0.04)])
    before = est.estimates()
    bad = detection(1, T_B, 0.08)
    bad.T_c_m[0, 3] = np.nan
    with pytest.raises(ValueError, match="board 1 by camera 'down'.*finite"):
        est.update(0.08, [detection(0, T_A, 0.08), bad])
    with pytest.raises(ValueError, match="finite 4x4"):
        est.update(0.08, [Detection("down", 1, np.eye(3), NO_CORNERS, (), 0.08)])
    with pytest.raises(ValueError, match="time goes backwards"):
        est.update(0.0, [])
    with pytest.raises(ValueError, match="time goes backwards"):
        est.set_static("b", True, 0.01)
    with pytest.raises(ValueError, match="time goes backwards"):
        est.add_robot("late", static=False, time=0.0)
    with pytest.raises(ValueError, match="finite"):
        est.update(float("nan"), [])
    with pytest.raises(ValueError, match="must be a number"):
        est.update("soon", [])  # type: ignore[arg-type]
    assert est.time == 0.04
    after = est.estimates()
    for name in before:
        assert np.array_equal(before[name].T_w_b, after[name].T_w_b)
        assert before[name].status is after[name].status
    est.update(0.04, [])  # the same time again is fine


# --------------------------------------------------------------------------- estimates, events
def test_initial_states_and_estimate_snapshots():
    est = top_observer(b_pose=False)
    est.add_robot("c", boards={2: BOARD_TOP}, static=True)  # static, pose unknown: settles when seen
    a, b, uav, c = (est.estimate(n) for n in ("a", "b", "uav", "c"))
    assert (a.phase, a.status, a.last_fresh_time, a.n_window) == (Phase.REFERENCE, Status.LOCALISED, 0.0, 0)
    np.testing.assert_array_equal(a.T_w_b, T_A)
    assert (b.phase, b.status, b.T_w_b, b.last_fresh_time) == (Phase.MOBILE, Status.LOST, None, None)
    assert (c.phase, c.status, c.T_w_b) == (Phase.SETTLING, Status.LOST, None)
    a.T_w_b[0, 3] = 99.0  # a copy: the estimator is unaffected
    assert est.estimate("a").T_w_b[0, 3] == T_A[0, 3]
    assert est.camera_pose("down") is None  # no update yet
    assert set(est.estimates()) == {"a", "b", "uav", "c"}
    assert est.events == ()
    assert EVENT_KINDS == ("static", "mobile", "frozen", "lost", "relocalised")


def test_camera_pose_and_robot_carrying_the_camera():
    est = top_observer()
    est.update(0.04, [detection(0, T_A, 0.04)])
    np.testing.assert_allclose(est.camera_pose("down"), T_W_C, atol=1e-12)
    est.camera_pose("down")[0, 0] = 5.0  # a copy
    np.testing.assert_allclose(est.camera_pose("down"), T_W_C, atol=1e-12)
    # The UAV's pose comes from its camera (after the gate's 3-sample start).
    for t in (0.08, 0.12):
        est.update(t, [detection(0, T_A, t)])
    np.testing.assert_allclose(est.estimate("uav").T_w_b, T_W_C @ g.invert(CAM_DOWN), atol=1e-12)
    assert est.estimate("uav").status is Status.LOCALISED


def test_camera_located_through_a_mobile_board_locates_nothing():
    # A second camera sees only b's board: b is mobile, so that camera is not
    # located and c (seen only by that camera) is not measured.
    est = top_observer(EstimatorConfig(gate=None))
    est.add_robot("c", boards={2: BOARD_TOP}, static=False, initial_pose=g.se2_to_se3(1.0, 1.0, 0.0))
    est.add_robot("hand", cameras={"hand": CAM_DOWN}, static=False)
    T_w_c2 = g.make_transform(g.rot_x(3.0), [0.8, 0.5, 1.5])
    T_c = g.se2_to_se3(1.1, 0.9, 0.3)
    est.update(
        0.04,
        [
            detection(0, T_A, 0.04),
            detection(1, T_B, 0.04),
            detection(1, T_B, 0.04, camera="hand", T_w_c=T_w_c2),
            detection(2, T_c, 0.04, camera="hand", T_w_c=T_w_c2),
        ],
    )
    np.testing.assert_allclose(est.estimate("b").T_w_b, T_B, atol=1e-12)
    assert est.camera_pose("hand") is None
    assert est.estimate("c").status is Status.HOLDING
    np.testing.assert_array_equal(est.estimate("c").T_w_b, g.se2_to_se3(1.0, 1.0, 0.0))


def test_settling_window_freezes_when_full_and_reports_its_mean():
    est = top_observer(EstimatorConfig(window=4, gate=None), b_static=False)
    est.set_static("b", True, 0.0)
    rng = np.random.default_rng(1)
    samples = []
    for k in range(1, 5):
        t = k * DT
        T_meas = T_B @ g.make_transform(g.rotvec_to_matrix(rng.normal(0, 0.01, 3)), rng.normal(0, 0.01, 3))
        samples.append(T_meas)
        est.update(t, [detection(0, T_A, t), detection(1, T_meas, t)])
        e = est.estimate("b")
        np.testing.assert_allclose(e.T_w_b, g.mean_pose(samples), atol=1e-12)
        assert e.status is Status.LOCALISED
        if k < 4:
            assert (e.phase, e.n_window) == (Phase.SETTLING, k)
    assert (e.phase, e.n_window) == (Phase.REFERENCE, 4)
    kinds = [(ev.robot, ev.kind, ev.n_samples) for ev in est.events]
    assert kinds == [("b", "static", 0), ("b", "frozen", 4)]
    # As a reference, b now locates the camera on its own.
    est.update(0.2, [detection(1, T_B, 0.2)])
    expected = est.estimate("b").T_w_b @ BOARD_TOP @ g.invert(g.invert(T_W_C) @ T_B @ BOARD_TOP)
    np.testing.assert_allclose(est.camera_pose("down"), expected, atol=1e-12)


def test_mobile_declaration_freezes_only_ready_settling_robots():
    est = MomaEstimator(EstimatorConfig(window=25, gate=None))
    assert est.config.min_window == 10
    est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_A)
    est.add_robot("b", boards={1: BOARD_TOP}, static=False, initial_pose=T_B)
    T_C = g.se2_to_se3(-0.5, 0.4, 1.0)
    est.add_robot("c", boards={2: BOARD_TOP}, static=False, initial_pose=T_C)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    est.set_static("b", True, 0.0)
    for k in range(1, 13):  # b gets 12 samples (>= min_window); c is not seen at all
        est.update(k * DT, [detection(0, T_A, k * DT), detection(1, T_B, k * DT)])
        assert est.window_ready("b") is (k >= 10)
    t = 12 * DT
    est.set_static("c", True, t)
    assert est.estimate("c").status is Status.HOLDING and est.estimate("c").n_window == 0
    assert not est.window_ready("c") and est.window_ready("a") and not est.window_ready("uav")
    est.set_static("a", False, t)
    b, c, a = est.estimate("b"), est.estimate("c"), est.estimate("a")
    assert (b.phase, b.n_window) == (Phase.REFERENCE, 12)
    np.testing.assert_allclose(b.T_w_b, T_B, atol=1e-12)
    # c has no window sample: it stays settling, is no reference, and its pose is not called fresh.
    assert (c.phase, c.n_window, c.status) == (Phase.SETTLING, 0, Status.HOLDING)
    assert (a.phase, a.status, a.last_fresh_time) == (Phase.MOBILE, Status.LOCALISED, t)
    frozen = {(e.robot, e.n_samples) for e in est.events if e.kind == "frozen"}
    assert frozen == {("b", 12)}
    assert est.events[-1].kind == "mobile" and est.events[-1].robot == "a"
    # Repeating a declaration does nothing.
    n = len(est.events)
    est.set_static("a", False, t)
    est.set_static("b", True, t)
    assert len(est.events) == n


def test_mobile_declaration_leaves_a_short_window_settling():
    est = MomaEstimator(EstimatorConfig(window=25, gate=None))
    T_C = g.se2_to_se3(-0.5, 0.4, 1.0)
    est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_A)
    est.add_robot("b", boards={1: BOARD_TOP}, static=False, initial_pose=T_B)
    est.add_robot("c", boards={2: BOARD_TOP}, static=True, initial_pose=T_C)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    est.set_static("b", True, 0.0)
    for k in range(1, 4):  # 3 samples < min_window
        est.update(k * DT, [detection(0, T_A, k * DT), detection(1, T_B, k * DT)])
    est.set_static("a", False, 3 * DT)
    assert est.estimate("b").phase is Phase.SETTLING and not est.window_ready("b")
    # It goes on collecting, now through c, and is frozen when its window is full.
    for k in range(4, 4 + 22):
        est.update(k * DT, [detection(2, T_C, k * DT), detection(1, T_B, k * DT)])
    assert [(e.robot, e.n_samples) for e in est.events if e.kind == "frozen"] == [("b", 25)]
    np.testing.assert_allclose(est.estimate("b").T_w_b, T_B, atol=1e-12)


def test_settle_delay_ignores_early_samples():
    est = top_observer(EstimatorConfig(window=3, settle_delay_s=0.1, gate=None))
    est.update(DT, [detection(0, T_A, DT), detection(1, T_B, DT)])
    est.set_static("b", True, DT)
    counts = []
    for k in range(2, 8):
        t = round(k * DT, 10)
        est.update(t, [detection(0, T_A, t), detection(1, T_B, t)])
        counts.append(est.estimate("b").n_window)
        if t - DT < 0.1:
            assert est.estimate("b").status is Status.HOLDING
    # Samples at 0.08 s (0.04 s after stopping) and 0.12 s (0.08 s) are ignored.
    assert counts[:5] == [0, 0, 1, 2, 3]
    assert est.estimate("b").phase is Phase.REFERENCE


# --------------------------------------------------------------------------- outlier gate
def test_gate_rejects_a_single_jump():
    est = top_observer()
    for k in range(1, 6):
        est.update(k * DT, [detection(0, T_A, k * DT), detection(1, T_B, k * DT)])
    assert est.estimate("b").status is Status.LOCALISED
    held = est.estimate("b").T_w_b
    jumped = T_B @ g.make_transform(t=[0.5, 0.0, 0.0])
    est.update(6 * DT, [detection(0, T_A, 6 * DT), detection(1, jumped, 6 * DT)])
    assert est.estimate("b").status is Status.HOLDING
    np.testing.assert_array_equal(est.estimate("b").T_w_b, held)
    est.update(7 * DT, [detection(0, T_A, 7 * DT), detection(1, T_B, 7 * DT)])
    assert est.estimate("b").status is Status.LOCALISED
    # Without the gate the jump is taken as is.
    est = top_observer(EstimatorConfig(gate=OutlierGateConfig(enabled=False)))
    est.update(DT, [detection(0, T_A, DT), detection(1, jumped, DT)])
    np.testing.assert_allclose(est.estimate("b").T_w_b, jumped, atol=1e-12)


def test_gate_start_needs_three_consistent_samples():
    est = top_observer(b_pose=False)
    wobble = [g.make_transform(t=[dx, 0.0, 0.0]) for dx in (0.0, 0.05, 0.0, 0.05, 0.0, 0.05)]
    for k, w in enumerate(wobble, start=1):  # consecutive samples 5 cm apart: never accepted
        est.update(k * DT, [detection(0, T_A, k * DT), detection(1, T_B @ w, k * DT)])
        assert est.estimate("b").status is Status.LOST and est.estimate("b").T_w_b is None
    for k in range(7, 10):
        est.update(k * DT, [detection(0, T_A, k * DT), detection(1, T_B, k * DT)])
        assert (est.estimate("b").status is Status.LOCALISED) == (k == 9)
    np.testing.assert_allclose(est.estimate("b").T_w_b, T_B, atol=1e-12)


def at(x: float, y: float, z: float, R: np.ndarray | None = None) -> np.ndarray:
    return g.make_transform(R, [x, y, z])


def test_gate_unit_behaviour():
    gate = OutlierGate(OutlierGateConfig())
    assert not gate.has_history
    assert [gate.accept(at(0.0, 0.0, 0.0), 0.0), gate.accept(at(0.01, 0.01, 0.0), 0.04)] == [False, False]
    assert gate.accept(at(0.02, 0.0, 0.01), 0.08)  # pairwise L1 <= 0.04
    assert gate.has_history
    assert not gate.accept(at(0.2, 0.0, 0.0), 0.12)  # 0.19 from the mean of the 3
    assert gate.accept(at(0.1, 0.0, 0.0), 0.16)  # 0.09 from it
    # After a gap longer than reset_after_s, history is forgotten: a restart is needed.
    assert not gate.accept(at(1.0, 1.0, 0.0), 1.5)
    assert not gate.accept(at(1.0, 1.0, 0.0), 1.54)
    assert gate.accept(at(1.0, 1.0, 0.0), 1.58)
    gate.reset(seed=at(5.0, 5.0, 0.0), time=2.0)
    assert gate.accept(at(5.1, 5.0, 0.0), 2.04)
    assert not gate.accept(at(5.0, 5.3, 0.0), 2.08)


def test_gate_rejects_a_rotation_jump_whose_position_is_within_tolerance():
    cfg = OutlierGateConfig()
    gate = OutlierGate(cfg)
    gate.reset(seed=at(0.0, 0.0, 0.3), time=0.0)
    flipped = at(0.05, 0.0, 0.3, g.rot_y(1.5 * cfg.jump_tolerance_rad))  # 5 cm: the position alone passes
    assert not gate.accept(flipped, 0.04)
    assert gate.accept(at(0.05, 0.0, 0.3, g.rot_y(0.5 * cfg.jump_tolerance_rad)), 0.08)
    # The start needs rotations pairwise within start_tolerance_rad too.
    gate = OutlierGate(cfg)
    twist = g.rot_x(1.2 * cfg.start_tolerance_rad)
    assert [gate.accept(at(0.0, 0.0, 0.0), 0.0), gate.accept(at(0.0, 0.0, 0.0, twist), 0.04)] == [False, False]
    assert not gate.accept(at(0.0, 0.0, 0.0), 0.08)
    assert not gate.accept(at(0.0, 0.0, 0.0), 0.12)  # the twisted one is still among the last 3
    assert gate.accept(at(0.0, 0.0, 0.0), 0.16)


def test_gate_config_names_rotation_fields():
    for name in ("start_tolerance_rad", "jump_tolerance_rad"):
        with pytest.raises(ConfigError, match=f"estimator.gate.{name}"):
            OutlierGateConfig(**{name: 0.0})


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.tuples(*[st.floats(-0.03, 0.03)] * 3), min_size=3, max_size=40),
    start=st.tuples(*[st.floats(-5, 5)] * 3),
)
def test_gate_accepts_every_smooth_stream_after_a_consistent_start(steps, start):
    """A stream moving < 3 cm per axis per sample (L1 < 0.09 < 0.15 - lag) is always accepted once started."""
    gate = OutlierGate(OutlierGateConfig())
    p = np.array(start)
    for _ in range(3):
        last = gate.accept(at(*p), 0.0)
    assert last
    for k, step in enumerate(steps, start=1):
        p = p + np.array(step) / 3.0  # mean-of-3 lag: at most 2 steps behind
        assert gate.accept(at(*p, g.rot_z(0.05 * k)), 0.04 * k)


# --------------------------------------------------------------------------- properties
rotvecs = st.tuples(*[st.floats(-3.0, 3.0)] * 3)
vectors = st.tuples(*[st.floats(-2.0, 2.0)] * 3)


def pose(rotvec, t) -> np.ndarray:
    return g.make_transform(g.rotvec_to_matrix(rotvec), t)


@settings(max_examples=60, deadline=None)
@given(rotvecs, vectors, rotvecs, vectors, rotvecs, vectors, rotvecs, vectors, rotvecs, vectors)
def test_zero_noise_chain_recovers_truth_for_any_geometry(r1, t1, r2, t2, r3, t3, r4, t4, r5, t5):
    """Any mounts, robot poses and camera pose: camera and mobile robot exact."""
    T_b_m0, T_b_m1, T_b_c = pose(r1, t1), pose(r2, t2), pose(r3, t3)
    T_w_a, T_w_b = pose(r4, t4), pose(r5, t5)
    T_w_uav = g.make_transform(g.rotvec_to_matrix(np.array(r1) * 0.5 + np.array(r5) * 0.3), np.array(t2) + (0, 0, 2))
    est = MomaEstimator(EstimatorConfig(gate=None))
    est.add_robot("a", boards={0: T_b_m0}, static=True, initial_pose=T_w_a)
    est.add_robot("b", boards={1: T_b_m1}, static=False)
    est.add_robot("uav", cameras={"c": T_b_c}, static=False)
    T_w_c = T_w_uav @ T_b_c
    est.update(1.0, [
        detection(0, T_w_a, 1.0, camera="c", T_w_c=T_w_c, mount=T_b_m0),
        detection(1, T_w_b, 1.0, camera="c", T_w_c=T_w_c, mount=T_b_m1),
    ])
    np.testing.assert_allclose(est.camera_pose("c"), T_w_c, atol=1e-9)
    np.testing.assert_allclose(est.estimate("b").T_w_b, T_w_b, atol=1e-9)
    np.testing.assert_allclose(est.estimate("uav").T_w_b, T_w_uav, atol=1e-9)
    assert est.estimate("b").status is Status.LOCALISED


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(rotvecs, vectors), min_size=1, max_size=12), rotvecs, vectors)
def test_switch_window_mean_is_geometry_mean_pose_of_its_inliers(perturbations, r0, t0):
    base = pose(r0, t0)
    poses = [base @ pose(np.array(r) * 0.02, np.array(t) * 0.02) for r, t in perturbations]
    window = SwitchWindow(len(poses))
    for T in poses:
        assert not window.full
        window.append(T)
    assert window.full and len(window) == len(poses)
    inliers = window.inliers()
    assert 1 <= len(inliers) <= len(poses)
    if len(poses) <= 2:
        assert inliers == list(range(len(poses)))
    np.testing.assert_allclose(window.mean(), g.mean_pose([poses[i] for i in inliers]), atol=1e-12)
    with pytest.raises(ValueError, match="already holds"):
        window.append(base)
    window.clear()
    with pytest.raises(ValueError, match="empty"):
        window.mean()


def test_switch_window_mean_is_not_dragged_by_flipped_samples():
    rng = np.random.default_rng(5)
    truth = g.make_transform(g.rot_z(0.7), [1.0, -0.5, 0.35])
    window = SwitchWindow(25)
    poses = []
    for k in range(25):
        if k in (3, 11, 19):  # the other planar-PnP pose: tilted by twice the viewing angle, shifted
            T = truth @ g.make_transform(g.rot_x(0.35), [0.0, 0.12, 0.0])
        else:
            T = truth @ pose(rng.normal(0.0, 0.005, 3), rng.normal(0.0, 0.003, 3))
        poses.append(T)
        window.append(T)
    assert sorted(set(range(25)) - set(window.inliers())) == [3, 11, 19]
    robust, plain = window.mean(), g.mean_pose(poses)
    assert np.linalg.norm(robust[:3, 3] - truth[:3, 3]) < 0.003
    assert np.linalg.norm(plain[:3, 3] - truth[:3, 3]) > 0.01
    assert g.rotation_angle(robust[:3, :3].T @ truth[:3, :3]) < 0.005




def test_fusion_of_two_references_uses_mean_pose():
    # Two references seen with inconsistent detections: the camera is their mean.
    est = MomaEstimator(EstimatorConfig(gate=None))
    est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_A)
    est.add_robot("b", boards={1: BOARD_TOP}, static=True, initial_pose=T_B)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    shifted = T_B @ g.make_transform(g.rot_z(0.02), [0.01, 0.0, 0.0])
    d0, d1 = detection(0, T_A, DT), detection(1, shifted, DT)
    est.update(DT, [d0, d1])
    c0 = T_A @ BOARD_TOP @ g.invert(d0.T_c_m)
    c1 = T_B @ BOARD_TOP @ g.invert(d1.T_c_m)
    np.testing.assert_allclose(est.camera_pose("down"), g.mean_pose([c0, c1]), atol=1e-12)
    assert not np.allclose(c0, c1)
    assert math.isclose(est.estimate("uav").last_fresh_time, DT)
