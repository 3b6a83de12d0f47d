"""The estimator's packed compiled calls give the bits of the calls they wrap.

A compiled call that returns an error's Jacobians, ``Q`` and ``P`` packed in one
array (:func:`~moma_env.estimator.uncertainty.pack_operands_kernel`, read back by
:meth:`LinearError.of_packed`) must give exactly the error the unpacked call and
:meth:`LinearError.of_operands` / :meth:`LinearError.of_jacobian` gave, and a
sample from a mounted frame exactly ``body_from_mounted_frame`` then
:meth:`LinearError.transformed` (the code it replaced in the update).
"""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.estimator.kernels import (
    body_from_mounted_frame,
    camera_from_reference_board,
    packed_camera_from_reference_board,
    packed_sample_from_board_seen,
    packed_sample_from_mounted_frame,
    sample_from_board_seen,
)
from moma_env.estimator.uncertainty import NO_MATRIX, LinearError, RunningErrorMean, noise_operands


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def same_error(a: LinearError, b: LinearError) -> bool:
    return (
        list(a.J) == list(b.J)
        and all(same_bits(a.J[s], b.J[s]) for s in a.J)
        and same_bits(a.Q, b.Q)
        and (a.P is None) == (b.P is None)
        and (a.P is None or same_bits(a.P, b.P))
    )


def random_pose(rng: np.random.Generator) -> np.ndarray:
    return g.make_transform(g.rotvec_to_matrix(rng.normal(0.0, 3.0, 3)), rng.normal(0.0, 2.0, 3))


def random_covariance(rng: np.random.Generator) -> np.ndarray:
    L = rng.normal(0.0, 0.01, (6, 6))
    return L @ L.T


def random_camera_error(rng: np.random.Generator, k: int) -> LinearError:
    keys = [[], ["a"], ["a", "b"], [3, "a", 7]][k % 4]
    return LinearError(
        {key: rng.normal(size=(6, 6)) for key in keys}, random_covariance(rng), random_covariance(rng) if k % 2 else None
    )


@pytest.mark.parametrize("seed", range(3))
def test_a_packed_sample_from_a_board_seen_is_the_unpacked_one_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for k in range(200):
        T_w_c, T_c_m, mount = (random_pose(rng) for _ in range(3))
        inverse = g.invert(mount)
        camera_error = random_camera_error(rng, k)
        cov = None if k % 5 == 0 else random_covariance(rng)
        persistent = None if cov is None or k % 3 == 0 else random_covariance(rng)
        planar = bool(k % 7 < 4)
        names, *operands = camera_error.operands()
        args = (T_w_c, T_c_m, mount, inverse, planar, 0.3, *operands, *noise_operands(cov, persistent))
        want_sample, *parts = sample_from_board_seen(*args)
        got_sample, packed, has_P = packed_sample_from_board_seen(*args)
        assert same_bits(got_sample, want_sample)
        assert same_error(LinearError.of_packed(names, packed, has_P), LinearError.of_operands(names, *parts))


@pytest.mark.parametrize("seed", range(3))
def test_a_packed_sample_from_a_mounted_frame_is_the_transformed_error_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for k in range(200):
        T_w_x, mount = random_pose(rng), random_pose(rng)
        inverse = g.invert(mount)
        error = random_camera_error(rng, k)
        planar = bool(k % 3)
        plane_z = float(rng.normal())
        want_sample, A = body_from_mounted_frame(T_w_x, mount, inverse, planar, plane_z if planar else 0.0)
        want = error.transformed(A)
        names, *operands = error.operands()
        got_sample, packed, has_P = packed_sample_from_mounted_frame(
            T_w_x, mount, inverse, planar, plane_z if planar else 0.0, *operands
        )
        assert same_bits(got_sample, want_sample)
        assert same_error(LinearError.of_packed(names, packed, has_P), want)


@pytest.mark.parametrize("seed", range(3))
def test_a_packed_camera_from_a_reference_board_is_the_unpacked_one_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for k in range(200):
        T_w_m, T_c_m = random_pose(rng), random_pose(rng)
        board_J = rng.normal(size=(6, 6))
        cov = None if k % 4 == 0 else random_covariance(rng)
        persistent = None if cov is None or k % 3 == 0 else random_covariance(rng)
        args = (
            T_w_m, board_J, T_c_m,
            NO_MATRIX if cov is None else cov, cov is not None,
            NO_MATRIX if persistent is None else persistent, persistent is not None,
        )
        T_w_c, J, Q, P = camera_from_reference_board(*args)
        got_T, packed = packed_camera_from_reference_board(*args)
        assert same_bits(got_T, T_w_c)
        want = LinearError.of_jacobian(k, J, Q, None if persistent is None else P)
        assert same_error(LinearError.of_packed((k,), packed, persistent is not None), want)


def test_the_running_mean_restarts_exactly_when_its_errors_are_not_a_prefix():
    """The prefix test is by identity: equal-looking but distinct errors start the sums afresh."""
    rng = np.random.default_rng(0)
    errors = [LinearError({0: rng.normal(size=(6, 6))}, random_covariance(rng)) for _ in range(5)]
    running = RunningErrorMean()
    first = running.mean(errors[:3])
    assert running.mean(list(errors[:3])) is first  # the same errors: the cached mean
    twin = LinearError({0: errors[1].J[0]}, errors[1].Q)  # the same arrays, another error
    again = running.mean([errors[0], twin, errors[2]])
    assert again is not first and same_error(again, first)
    assert same_error(running.mean(errors), LinearError.mean(list(errors)))
