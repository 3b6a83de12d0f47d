"""End-to-end MOMA scenarios on synthetic detections (no camera module).

Detections are built from known true poses: ``T_c_m = inv(T_w_c) @ T_w_m``,
optionally perturbed by bounded, seeded noise in the board frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.estimator import (
    Detection,
    EstimatorConfig,
    MomaEstimator,
    Phase,
    Status,
)

DT = 0.04  # 25 Hz
BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.02, -0.01, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.03, 0.0, -0.05])
CAM_FORWARD = g.make_transform(g.R_BODY_CAM_FORWARD, [0.20, 0.0, 0.30])
BOARD_BACK = g.make_transform(g.R_BODY_BOARD_BACK, [-0.25, 0.0, 0.30])
NO_CORNERS = np.empty((0, 2))


def detect(camera_id: str, T_w_c: np.ndarray, board_id: int, T_w_m: np.ndarray, t: float,
           noise: np.ndarray | None = None) -> Detection:
    """A detection of the board at ``T_w_m`` by the camera at ``T_w_c`` (noise in M)."""
    T_c_m = g.invert(T_w_c) @ T_w_m
    if noise is not None:
        T_c_m = T_c_m @ noise
    return Detection(camera_id, board_id, T_c_m, NO_CORNERS, (), t)


def bounded_noise(rng: np.random.Generator, t_max: float, r_max: float) -> np.ndarray:
    """Rigid perturbation: rotation vector and translation components uniform in +-r_max / +-t_max."""
    return g.make_transform(g.rotvec_to_matrix(rng.uniform(-r_max, r_max, 3)), rng.uniform(-t_max, t_max, 3))


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> float:
    """Largest absolute difference of the matrices (translation in m, rotation entries)."""
    return float(np.abs(T_est - T_true).max())


def position_error(T_est: np.ndarray, T_true: np.ndarray) -> float:
    return float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]))


def rotation_error(T_est: np.ndarray, T_true: np.ndarray) -> float:
    return g.rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])


# --------------------------------------------------------------------------- top observer
@dataclass
class Frame:
    """What the test saw after one update and the declarations at that time."""

    time: float
    truth: dict[str, np.ndarray]
    estimates: dict
    camera_truth: np.ndarray
    camera_estimate: np.ndarray | None
    events: tuple = ()


@dataclass
class TopObserverRun:
    """Leapfrog of ``n_robots`` UGVs under a UAV whose camera moves and tilts every frame."""

    n_robots: int
    seed: int
    config: EstimatorConfig = field(default_factory=EstimatorConfig)
    noise: tuple[float, float] | None = None  # (t_max m, r_max rad)
    tilt_only_noise: bool = False  # rotation noise about the board's x and y axes only
    tilt: float = 0.08  # rad, random roll and pitch every frame
    planar: bool = False  # declare the UGVs upright ground robots

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.noise_rng = np.random.default_rng(self.seed + 1000)
        self.names = [f"ugv_{i}" for i in range(self.n_robots)]
        self.truth = {
            name: g.se2_to_se3(0.6 * i, 0.1 * i, float(self.rng.uniform(-math.pi, math.pi)))
            for i, name in enumerate(self.names)
        }
        self.est = MomaEstimator(self.config)
        for i, name in enumerate(self.names):
            self.est.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=self.truth[name], planar=self.planar)
        self.est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
        self.t = 0.0
        self.frames: list[Frame] = []

    def uav_body(self) -> np.ndarray:
        t = self.t
        R = g.rot_z(0.2 * t) @ g.rot_y(float(self.rng.uniform(-self.tilt, self.tilt))) @ g.rot_x(
            float(self.rng.uniform(-self.tilt, self.tilt))
        )
        return g.make_transform(R, [0.5 + 0.3 * math.cos(0.4 * t), 0.2 + 0.3 * math.sin(0.4 * t), 2.0 + 0.05 * math.sin(t)])

    def step(self, declarations: Callable[[], None] | None = None) -> Frame:
        self.t = round(self.t + DT, 10)
        T_w_c = self.uav_body() @ CAM_DOWN
        dets = []
        for i, name in enumerate(self.names):
            noise = None if self.noise is None else bounded_noise(self.noise_rng, *self.noise)
            if noise is not None and self.tilt_only_noise:
                noise[:3, :3] = g.rot_x(math.asin(noise[2, 1])) @ g.rot_y(math.asin(noise[0, 2]))
            dets.append(detect("down", T_w_c, i, self.truth[name] @ BOARD_TOP, self.t, noise))
        n_events = len(self.est.events)
        self.est.update(self.t, dets)
        if declarations is not None:
            declarations()
        frame = Frame(
            self.t,
            {k: v.copy() for k, v in self.truth.items()} | {"uav": T_w_c @ g.invert(CAM_DOWN)},
            self.est.estimates(),
            T_w_c,
            self.est.camera_pose("down"),
            self.est.events[n_events:],
        )
        self.frames.append(frame)
        return frame

    def run(self, n_switches: int, dwell_range: tuple[int, int] = (3, 35)) -> None:
        for _ in range(5):
            self.step()
        for k in range(n_switches):
            mover = self.names[k % self.n_robots]
            # The owner waits until every other robot's window is ready (as the env's rules do).
            while not all(self.est.window_ready(n) for n in self.names if n != mover):
                self.step()
            self.est.set_static(mover, False, self.t)
            x0, y0, yaw0 = g.se3_to_se2(self.truth[mover])
            x1 = float(np.clip(x0 + self.rng.uniform(-0.4, 0.4), -0.5, 1.5))
            y1 = float(np.clip(y0 + self.rng.uniform(-0.4, 0.4), -0.5, 1.0))
            yaw1 = yaw0 + float(self.rng.uniform(-1.0, 1.0))
            n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / 0.01))
            for j in range(1, n + 1):
                f = j / n
                self.truth[mover] = g.se2_to_se3(x0 + f * (x1 - x0), y0 + f * (y1 - y0), yaw0 + f * (yaw1 - yaw0))
                last = j == n
                self.step((lambda m=mover: self.est.set_static(m, True, self.t)) if last else None)
            for _ in range(int(self.rng.integers(*dwell_range))):
                self.step()


@pytest.mark.parametrize("n_robots", [2, 3])
def test_top_observer_zero_noise_is_exact_through_many_switches(n_robots):
    run = TopObserverRun(n_robots, seed=10 + n_robots)
    run.run(n_switches=25)
    frozen = [e for e in run.est.events if e.kind == "frozen"]
    assert len(frozen) >= 24  # the last mover may still be settling at the end
    # Both ways of freezing happen: a full window and a forced freeze at a mobile declaration.
    assert any(e.n_samples == run.config.window for e in frozen)
    assert any(0 < e.n_samples < run.config.window for e in frozen)
    for k, frame in enumerate(run.frames):
        for name, est in frame.estimates.items():
            if name == "uav" and k < 2:
                assert est.status is Status.LOST  # the gate's start needs 3 samples
                continue
            assert est.status is Status.LOCALISED, (frame.time, name)
            assert pose_error(est.T_w_b, frame.truth[name]) < 1e-9, (frame.time, name)
        assert frame.camera_estimate is not None
        assert pose_error(frame.camera_estimate, frame.camera_truth) < 1e-9


def test_planar_robots_zero_noise_is_exact_and_upright():
    run = TopObserverRun(3, seed=21, planar=True)
    run.run(n_switches=12)
    for frame in run.frames[3:]:
        for name, est in frame.estimates.items():
            assert pose_error(est.T_w_b, frame.truth[name]) < 1e-9, (frame.time, name)
            if name != "uav":
                np.testing.assert_array_equal(est.T_w_b[2], [0.0, 0.0, 1.0, 0.0])


def test_planar_constraint_reduces_the_position_error_of_tilted_measurements():
    errors = {}
    for planar in (False, True):
        # A face-on board's pose is well determined but for its tilt (the planar
        # PnP ambiguity): tilt noise of 0.05 rad, 2 mm of translation noise.
        run = TopObserverRun(2, seed=5, noise=(0.002, 0.05), tilt_only_noise=True, planar=planar)
        run.run(n_switches=10)
        errors[planar] = np.mean(
            [np.linalg.norm(f.estimates[n].T_w_b[:2, 3] - f.truth[n][:2, 3]) for f in run.frames[3:] for n in run.names]
        )
    # The floor position error, which is what the projection at the mount targets.
    assert errors[True] < 0.5 * errors[False], errors


def test_top_observer_uses_every_phase():
    run = TopObserverRun(2, seed=3)
    run.run(n_switches=4)
    phases = {est.phase for frame in run.frames for est in frame.estimates.values()}
    assert phases == {Phase.MOBILE, Phase.SETTLING, Phase.REFERENCE}


# --------------------------------------------------------------------------- caterpillar
def path_pose(s: float) -> np.ndarray:
    """Pose on a gently curving path at arc parameter ``s`` (m)."""
    return g.se2_to_se3(s, 0.1 * math.sin(s), math.atan(0.1 * math.cos(s)))


def test_caterpillar_zero_noise_is_exact_through_many_cycles():
    cfg = EstimatorConfig(window=10, settle_delay_s=0.2)
    est = MomaEstimator(cfg)
    s = {"leader": 0.95, "follower": 0.0}  # board 0.5 m in front of the camera
    est.add_robot("leader", boards={7: BOARD_BACK}, static=True, initial_pose=path_pose(s["leader"]))
    est.add_robot("follower", cameras={"front": CAM_FORWARD}, static=True, initial_pose=path_pose(s["follower"]))
    t = 0.0
    checked = 0
    statuses = set()

    def frame() -> None:
        nonlocal t, checked
        t = round(t + DT, 10)
        T_w_c = path_pose(s["follower"]) @ CAM_FORWARD
        T_w_m = path_pose(s["leader"]) @ BOARD_BACK
        T_c_m = g.invert(T_w_c) @ T_w_m
        assert 0.4 < T_c_m[2, 3] < 0.9  # the board is in front of the camera
        est.update(t, [Detection("front", 7, T_c_m, NO_CORNERS, (), t)])
        for name in s:
            e = est.estimate(name)
            statuses.add(e.status)
            assert e.T_w_b is not None
            assert pose_error(e.T_w_b, path_pose(s[name])) < 1e-9, (t, name, e.status)
            checked += 1
        assert pose_error(est.camera_pose("front"), T_w_c) < 1e-9

    for _cycle in range(12):
        for mover in ("leader", "follower"):
            est.set_static(mover, False, t)
            for _ in range(15):
                s[mover] += 0.02
                frame()
            est.set_static(mover, True, t)
            for _ in range(20):  # 0.2 s settle delay (5 frames) + 10-sample window + margin
                frame()
            assert est.estimate(mover).phase is Phase.REFERENCE
    frozen = [e for e in est.events if e.kind == "frozen"]
    assert len(frozen) == 24 and all(e.n_samples == 10 for e in frozen)
    # The settle delay shows: right after stopping, the pose is held, not fresh.
    assert Status.HOLDING in statuses
    assert checked == 24 * 35 * 2


# --------------------------------------------------------------------------- noise
def test_with_noise_references_are_frozen_and_mobile_error_is_bounded():
    t_max, r_max = 0.002, 0.002
    run = TopObserverRun(2, seed=7, noise=(t_max, r_max))
    run.run(n_switches=20)
    names = run.names
    freezes = {(e.time, e.robot) for e in run.est.events if e.kind == "frozen"}
    frozen_values = {name: [] for name in names}
    checked_ref = checked_mobile = 0
    for prev, frame in zip(run.frames, run.frames[1:]):
        for name in names:
            est, before = frame.estimates[name], prev.estimates[name]
            if est.phase is Phase.REFERENCE:
                if before.phase is Phase.REFERENCE:
                    # Bit-identical pose, hence identical error, between switches.
                    assert np.array_equal(est.T_w_b, before.T_w_b), (frame.time, name)
                    assert np.array_equal(frame.truth[name], prev.truth[name])
                    checked_ref += 1
                else:
                    # It became a reference by a freeze (in this update or at a
                    # declaration made after the previous frame was recorded).
                    assert (frame.time, name) in freezes or (prev.time, name) in freezes
                    frozen_values[name].append(est.T_w_b)
        movers = [n for n in names if frame.estimates[n].phase is Phase.MOBILE]
        for mover in movers:
            (ref,) = [n for n in names if n != mover]
            ref_est = frame.estimates[ref]
            assert ref_est.phase is Phase.REFERENCE
            e_pos = position_error(ref_est.T_w_b, frame.truth[ref])
            e_rot = rotation_error(ref_est.T_w_b, frame.truth[ref])
            lever = float(np.linalg.norm(frame.truth[ref][:3, 3] - frame.truth[mover][:3, 3])) + 0.5
            s3 = math.sqrt(3.0)
            bound = e_pos + e_rot * lever + 2 * s3 * t_max + s3 * r_max * (lever + 0.5)
            est = frame.estimates[mover]
            assert est.status is Status.LOCALISED
            assert position_error(est.T_w_b, frame.truth[mover]) <= bound, (frame.time, mover)
            checked_mobile += 1
    assert checked_ref > 200 and checked_mobile > 200
    # Every freeze gives a new (noisy) value: the error changes at freezes, and only there.
    for name in names:
        values = frozen_values[name]
        assert len(values) >= 9
        assert all(not np.array_equal(a, b) for a, b in zip(values, values[1:]))


def test_window_average_reduces_switch_error():
    t_max, r_max = 0.003, 0.003
    rng = np.random.default_rng(2024)

    def frozen_error(window: int, trial_seed: int) -> float:
        trial = np.random.default_rng(trial_seed)
        est = MomaEstimator(EstimatorConfig(window=window, gate=None))
        T_a = g.se2_to_se3(0.0, 0.0, float(trial.uniform(-3, 3)))
        T_b = g.se2_to_se3(0.6, 0.2, float(trial.uniform(-3, 3)))
        est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_a)
        est.add_robot("b", boards={1: BOARD_TOP}, static=True)  # unknown pose: settles
        est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
        t = 0.0
        while est.estimate("b").phase is not Phase.REFERENCE:
            t += DT
            hover = g.make_transform(g.rot_z(0.3) @ g.rot_x(float(trial.uniform(-0.05, 0.05))), [0.3, 0.1, 1.8])
            T_w_c = hover @ CAM_DOWN
            est.update(t, [
                detect("down", T_w_c, 0, T_a @ BOARD_TOP, t, bounded_noise(trial, t_max, r_max)),
                detect("down", T_w_c, 1, T_b @ BOARD_TOP, t, bounded_noise(trial, t_max, r_max)),
            ])
        assert est.estimate("b").n_window == window
        return position_error(est.estimate("b").T_w_b, T_b)

    seeds = rng.integers(0, 2**32, size=150)
    single = np.mean([frozen_error(1, int(s)) for s in seeds])
    averaged = np.mean([frozen_error(25, int(s)) for s in seeds])
    assert single > 0.003  # the noise is visible at all
    assert averaged < 0.4 * single  # ~1/sqrt(25) expected


# --------------------------------------------------------------------------- lost / relocalised
def test_lost_reference_holding_then_lost_then_relocalised():
    est = MomaEstimator(EstimatorConfig(lost_after_s=2.0))
    T_a = g.se2_to_se3(0.0, 0.0, 0.3)
    T_b = g.se2_to_se3(0.6, 0.0, -0.2)
    est.add_robot("a", boards={0: BOARD_TOP}, static=True, initial_pose=T_a)
    est.add_robot("b", boards={1: BOARD_TOP}, static=False, initial_pose=T_b)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    T_w_c = g.make_transform(g.rot_z(0.1), [0.3, 0.0, 2.0]) @ CAM_DOWN
    t = 0.0

    def step(boards: dict[int, np.ndarray]) -> None:
        nonlocal t
        t = round(t + DT, 10)
        est.update(t, [detect("down", T_w_c, i, T @ BOARD_TOP, t) for i, T in boards.items()])

    for _ in range(10):
        step({0: T_a, 1: T_b})
    assert est.estimate("b").status is Status.LOCALISED
    last_pose, last_time = est.estimate("b").T_w_b, t
    np.testing.assert_allclose(last_pose, T_b, atol=1e-12)

    # b drives away unseen: holding its last pose, then lost after 2 s, never fresh.
    T_b = g.se2_to_se3(1.1, 0.2, 0.4)
    statuses = []
    while t < last_time + 3.0:
        step({0: T_a})
        e = est.estimate("b")
        assert np.array_equal(e.T_w_b, last_pose)
        assert e.last_fresh_time == last_time
        expected = Status.LOST if t - last_time > 2.0 else Status.HOLDING
        assert e.status is expected, (t, e.status)
        statuses.append(e.status)
        assert est.camera_pose("down") is not None
    assert Status.HOLDING in statuses and Status.LOST in statuses
    lost = [e for e in est.events if e.kind == "lost"]
    assert len(lost) == 1 and lost[0].robot == "b" and lost[0].time - last_time > 2.0
    assert lost[0].time - last_time <= 2.0 + DT + 1e-9

    # The camera sees no reference: it is not located, the UAV holds.
    for _ in range(5):
        step({})
        assert est.camera_pose("down") is None
        assert est.estimate("uav").status is Status.HOLDING
        assert est.estimate("b").status is Status.LOST

    # b seen again: the gate (history older than 1 s) re-acquires it with 3 samples.
    for k in range(3):
        step({0: T_a, 1: T_b})
        e = est.estimate("b")
        if k < 2:
            assert e.status is Status.LOST and np.array_equal(e.T_w_b, last_pose)
        else:
            assert e.status is Status.LOCALISED
            np.testing.assert_allclose(e.T_w_b, T_b, atol=1e-12)
    relocalised = [e for e in est.events if e.kind == "relocalised"]
    assert [(e.robot, e.time) for e in relocalised] == [("b", t)]
