"""The estimator's fourth round of fast paths give the bits and the decisions of the code they replaced.

:func:`~moma_env.estimator.window.store_sample_kernel` (a switch window's sample stored
in one compiled call) must write the rows and decide finiteness exactly as the Python of
``SwitchWindow.append`` it replaced (kept below as the reference), and
:class:`~moma_env.estimator.uncertainty.RunningErrorMean` must give the plain mean's bits
whatever changes its list of errors goes through (deletions, insertions, truncations).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from error_bits import assert_same_error, same_bits

from moma_env.estimator.results import Phase, RobotEstimate, Status
from moma_env.estimator.uncertainty import LinearError, RunningErrorMean
from moma_env.estimator.window import SwitchWindow, store_sample_kernel


def reference_store(T: np.ndarray, rotations: np.ndarray, xyz: np.ndarray, n: int) -> bool:
    """The replaced Python of ``SwitchWindow.append``: the rows and the finite test."""
    rows = T.tolist()
    r0, r1, r2 = rows[0], rows[1], rows[2]
    rotations[n] = (r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2])
    xyz[n] = (r0[3], r1[3], r2[3])
    return math.isfinite(sum(r0) + sum(r1) + sum(r2) + sum(rows[3]))


def random_pose_like(rng: np.random.Generator) -> np.ndarray:
    T = rng.normal(size=(4, 4)) * 10.0 ** rng.integers(-3, 4)
    u = rng.random()
    if u < 0.15:
        T[rng.integers(4), rng.integers(4)] = rng.choice([np.inf, -np.inf, np.nan])
    elif u < 0.3:  # finite entries whose sum overflows
        T[rng.integers(4), rng.integers(4)] = 1e308
        T[rng.integers(4), rng.integers(4)] = 1e308
    elif u < 0.4:
        T[rng.integers(4), rng.integers(4)] = -0.0
    return T


@pytest.mark.parametrize("seed", range(6))
def test_the_sample_store_kernel_is_the_python_it_replaced(seed):
    rng = np.random.default_rng(seed)
    for trial in range(200):
        T = random_pose_like(rng)
        n = int(rng.integers(5))
        rot_a, xyz_a = rng.normal(size=(5, 9)), rng.normal(size=(5, 3))
        rot_b, xyz_b = rot_a.copy(), xyz_a.copy()
        assert store_sample_kernel(T, rot_a, xyz_a, n) == reference_store(T, rot_b, xyz_b, n)
        assert same_bits(rot_a, rot_b) and same_bits(xyz_a, xyz_b)


def test_a_window_refuses_a_sample_that_is_not_4x4():
    window = SwitchWindow(3)
    with pytest.raises(ValueError, match="4x4"):
        window.append(np.eye(3))
    assert len(window) == 0
    window.append(np.eye(4).tolist())  # any 4x4 array-like, as before
    assert len(window) == 1


def test_robot_estimate_is_still_a_frozen_record():
    T, C = np.eye(4), np.eye(6)
    e = RobotEstimate("a", T, Status.HOLDING, Phase.SETTLING, 1.5, 3)
    assert (e.name, e.T_w_b, e.status, e.phase, e.last_fresh_time, e.n_window, e.covariance) == (
        "a", T, Status.HOLDING, Phase.SETTLING, 1.5, 3, None
    )
    f = RobotEstimate(name="b", T_w_b=None, status=Status.LOST, phase=Phase.MOBILE, last_fresh_time=None, n_window=0, covariance=C)
    assert f.covariance is C and f.T_w_b is None
    with pytest.raises(AttributeError):
        e.name = "c"  # type: ignore[misc]
    with pytest.raises(TypeError):
        RobotEstimate("a", T, Status.LOST, Phase.MOBILE, None)  # type: ignore[call-arg]


def reference_mean(errors: list[LinearError]) -> LinearError:
    """The plain mean: a running mean that has summed nothing yet, so adds every error afresh."""
    return RunningErrorMean().mean(list(errors))


@pytest.mark.parametrize("seed", range(6))
def test_the_running_mean_gives_the_plain_means_bits_through_any_changes(seed):
    rng = np.random.default_rng(seed)
    for _ in range(2):
        running = RunningErrorMean()
        pool = [
            LinearError(
                {s: rng.normal(size=(6, 6)) for s in range(3) if rng.random() < 0.6},
                rng.normal(size=(6, 6)),
                rng.normal(size=(6, 6)) if rng.random() < 0.3 else None,
            )
            for _ in range(12)
        ]
        errors: list[LinearError] = []
        for _ in range(80):
            u = rng.random()
            if u < 0.3 and errors:
                del errors[int(rng.integers(len(errors)))]  # an inlier turned outlier
            elif u < 0.4 and errors:
                errors.insert(int(rng.integers(len(errors))), pool[int(rng.integers(len(pool)))])
            elif u < 0.5:
                errors = errors[: int(rng.integers(len(errors) + 1))]
            else:
                errors.append(pool[int(rng.integers(len(pool)))])
            if not errors:
                continue
            got, want = running.mean(errors), reference_mean(errors)
            assert_same_error(got, want)
            assert running.mean(list(errors)) is got
