"""A sample's error used as its compiled call packed it gives the bits of the LinearError.

The estimator's update hands a robot's single sample to its switch window
(:meth:`SettlingWindow.add_operands`) or to the covariance
(:func:`covariance_of_operands`) as the operands of the packed array
(:func:`packed_operands`), without making a :class:`LinearError` of it; and it passes a
detection's C-ordered arrays on as they are. Each is compared here, bit for bit, with
what the LinearError or the converted arrays give.
"""

from __future__ import annotations

import numpy as np
import pytest
from error_bits import assert_same_error, random_joint, same_bits

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator
from moma_env.estimator.uncertainty import LinearError, covariance_of_operands, pack_operands_kernel, packed_operands
from moma_env.estimator.window import SettlingWindow

#: A window whose samples are not all finite may keep no inlier: numpy divides by zero.
pytestmark = pytest.mark.filterwarnings("ignore:.*encountered in divide:RuntimeWarning")

KEYS = [4, 9, 2]
NO_CORNERS = np.zeros((0, 2))


def packed_error(rng: np.random.Generator, k: int, with_P: bool) -> tuple[list, np.ndarray, bool]:
    """``(keys, packed, has_P)`` of a random error with ``k`` references, as a compiled sample gives it."""
    keys = list(rng.permutation(KEYS)[:k].tolist())
    Js = rng.normal(size=(k, 6, 6))
    Q = rng.normal(size=(6, 6))
    Q[2, 3] = -0.0
    P = rng.normal(size=(6, 6)) if with_P else np.zeros((6, 6))
    return keys, pack_operands_kernel(Js, Q @ Q.T if rng.random() < 0.5 else Q, P), with_P


@pytest.mark.parametrize("k", [0, 1, 3])
@pytest.mark.parametrize("with_P", [False, True])
def test_packed_operands_are_the_operands_of_the_packed_error(k, with_P):
    rng = np.random.default_rng(10 * k + with_P)
    keys, packed, has_P = packed_error(rng, k, with_P)
    got = packed_operands(keys, packed, has_P)
    want = LinearError.of_packed(keys, packed, has_P).operands()
    assert got[0] == want[0] and got[4] == want[4] == with_P
    for a, b in zip(got[1:4], want[1:4], strict=True):
        assert same_bits(a, b)


@pytest.mark.parametrize("k", [0, 1, 3])
def test_covariance_of_operands_is_the_error_s_covariance(k):
    rng = np.random.default_rng(k)
    joint = random_joint(rng, KEYS)
    for with_P in (False, True):
        keys, packed, has_P = packed_error(rng, k, with_P)
        error = LinearError.of_packed(keys, packed, has_P)
        got = covariance_of_operands(*packed_operands(keys, packed, has_P)[:3], joint)
        assert same_bits(got, error.covariance(joint))
        # The operands of any error (a copy of its Jacobians, stacked) give it too.
        assert same_bits(covariance_of_operands(*error.operands()[:3], joint), error.covariance(joint))


def random_pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    scale = 0.2 if rng.random() < 0.15 else 0.002  # some outliers
    T[:3, :3] = g.rotvec_to_matrix(rng.normal(size=3) * scale)
    T[:3, 3] = rng.normal(size=3) * scale
    return T


@pytest.mark.parametrize("seed", range(4))
def test_a_window_given_operands_keeps_what_it_keeps_given_errors(seed):
    rng = np.random.default_rng(seed)
    joint = random_joint(rng, KEYS)
    by_error = SettlingWindow(25, joint=joint)
    by_operands = SettlingWindow(25, joint=joint)
    for _ in range(80):
        if by_error.full or rng.random() < 0.05:
            by_error.clear()
            by_operands.clear()
        T = random_pose(rng)
        keys, packed, has_P = packed_error(rng, int(rng.integers(0, 4)), rng.random() < 0.3)
        pose, covariance = by_error.add(T, LinearError.of_packed(keys, packed, has_P))
        got_pose, got_covariance = by_operands.add_operands(T, *packed_operands(keys, packed, has_P))
        assert same_bits(got_pose, pose) and same_bits(got_covariance, covariance)
        assert by_operands.inliers() == by_error.inliers()
        assert_same_error(by_operands.mean_error(), by_error.mean_error())
        for got, want in zip(by_operands.payloads(), by_error.payloads(), strict=True):
            assert_same_error(got, want)
    packed[:] = np.nan  # the operands were read, not kept
    assert_same_error(by_operands.mean_error(), by_error.mean_error())


def test_operands_of_other_shapes_are_refused_before_anything_is_stored():
    rng = np.random.default_rng(0)
    window = SettlingWindow(3, joint=random_joint(rng, KEYS))
    keys, packed, has_P = packed_error(rng, 2, False)
    keys_, stack, Q, P, has_P = packed_operands(keys, packed, has_P)
    for bad in ((keys_[:1], stack, Q, P), (keys_, stack, Q[:3], P), (keys_, stack, Q, np.zeros((6, 5)))):
        with pytest.raises(ValueError, match="6x6"):
            window.add_operands(np.eye(4), *bad, has_P)
    assert len(window) == 0 and window.references() == []
    window.add_operands(np.eye(4), keys_, stack, Q, P, has_P)
    assert len(window) == 1


def board_estimator() -> MomaEstimator:
    """A reference robot, a robot that moves and settles, and a UAV that sees both."""
    est = MomaEstimator(EstimatorConfig())
    est.add_robot("a", boards={0: np.eye(4)}, static=True, initial_pose=np.eye(4))
    est.add_robot("b", boards={1: np.eye(4)}, static=True, initial_pose=g.make_transform(np.eye(3), [1.0, 0.0, 0.0]))
    est.add_robot("uav", cameras={"down": np.eye(4)}, static=False)
    return est


def detections(rng: np.random.Generator, t: float, b_x: float, layout) -> list[Detection]:
    """The UAV's detections of both boards at time ``t`` (s), the arrays laid out by ``layout``."""
    T_w_c = g.make_transform(g.rot_x(np.pi), [0.5, 0.0, 2.0])
    out = []
    for board, x in ((0, 0.0), (1, b_x)):
        T_w_m = g.make_transform(g.rot_z(0.01 * rng.normal()), [x + 0.001 * rng.normal(), 0.001 * rng.normal(), 0.0])
        L = rng.normal(0.0, 0.003, (6, 6))
        cov = L @ L.T
        persistent = 0.5 * cov if board == 1 and rng.random() < 0.3 else None
        T_c_m = g.invert(T_w_c) @ T_w_m
        out.append(
            Detection(
                "down", board, layout(T_c_m), NO_CORNERS, (), t, covariance=layout(cov),
                persistent_covariance=None if persistent is None else layout(persistent),
            )
        )
    return out


@pytest.mark.parametrize("layout", [np.asfortranarray, lambda M: np.repeat(M, 2, axis=1)[:, ::2]], ids=["fortran", "strided"])
def test_detections_in_any_memory_order_give_the_same_estimates(layout):
    c_ordered, other = board_estimator(), board_estimator()
    rng_c, rng_o = np.random.default_rng(3), np.random.default_rng(3)
    b_x, t = 1.0, 0.0
    for step in range(160):
        t += 0.04
        phase = (step // 40) % 2  # b moves for 40 frames, then settles for 40
        if step % 40 == 0:
            for est in (c_ordered, other):
                est.set_static("b", phase == 1, t)
        if phase == 0:
            b_x += 0.01
        c_ordered.update(t, detections(rng_c, t, b_x, np.ascontiguousarray))
        other.update(t, detections(rng_o, t, b_x, layout))
        for name in ("b", "uav"):
            want, got = c_ordered.estimate(name), other.estimate(name)
            assert got.phase == want.phase and got.status == want.status
            assert same_bits(got.T_w_b, want.T_w_b) and same_bits(got.covariance, want.covariance)
    kinds = [e.kind for e in c_ordered.events]
    assert "frozen" in kinds and "mobile" in kinds
    assert [(e.time, e.robot, e.kind, e.n_samples) for e in other.events] == [
        (e.time, e.robot, e.kind, e.n_samples) for e in c_ordered.events
    ]
