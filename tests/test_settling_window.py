"""The settling window's one compiled call gives the bits of the code it replaced.

:class:`~moma_env.estimator.window.SettlingWindow` stores a sample with its error and
returns the mean pose and the covariance of the mean's error in one call. The reference
here is what the estimator computed before: a :class:`SwitchWindow` of the poses for the
inliers and the mean, the window mean of the inliers' errors (``reference_mean_error`` of
tests/error_bits.py, as the former ``RunningErrorMean(window=True)`` computed it) and
:meth:`LinearError.covariance` under the joint covariance. Every pose, covariance and
error is compared bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from error_bits import assert_same_error, random_joint, reference_mean_error, same_bits

from moma_env.estimator.uncertainty import LinearError
from moma_env.estimator.window import SettlingWindow, SwitchWindow
from moma_env.geometry import rotvec_to_matrix

#: A window whose samples are not all finite may keep no inlier: numpy divides by zero, as before.
pytestmark = pytest.mark.filterwarnings("ignore:.*encountered in divide:RuntimeWarning")

KEYS = [3, 7, 11]


def random_error(rng: np.random.Generator) -> LinearError:
    keys = [s for s in rng.permutation(KEYS).tolist() if rng.random() < 0.5]
    Q = rng.normal(size=(6, 6))
    Q[0, 1] = -0.0  # kept as it is by a one-sample mean, turned +0.0 by a sum from zero
    P = rng.normal(size=(6, 6)) if rng.random() < 0.3 else None
    return LinearError({s: rng.normal(size=(6, 6)) for s in keys}, Q @ Q.T if rng.random() < 0.5 else Q, P)


def random_pose(rng: np.random.Generator, centre: np.ndarray) -> np.ndarray:
    u = rng.random()
    scale = 0.2 if u < 0.15 else 0.001  # some outliers
    T = np.eye(4)
    T[:3, :3] = rotvec_to_matrix(rng.normal(size=3) * scale) @ centre[:3, :3]
    T[:3, 3] = centre[:3, 3] + rng.normal(size=3) * scale
    if u > 0.985:
        T[0, 3] = np.nan  # a sample that is not finite: numpy's statistics from then on
    return T


@pytest.mark.parametrize("seed", range(8))
def test_one_call_gives_the_mean_and_covariance_of_the_replaced_code(seed):
    rng = np.random.default_rng(seed)
    joint = random_joint(rng, KEYS)
    capacity = int(rng.integers(1, 26))
    window = SettlingWindow(capacity, joint=joint)
    reference = SwitchWindow(capacity)
    centre = np.eye(4)
    centre[:3, :3] = rotvec_to_matrix(rng.normal(size=3))
    for step in range(120):
        if window.full or rng.random() < 0.03:
            window.clear()
            reference.clear()
            assert len(window) == 0 and window.references() == []
        T, error = random_pose(rng, centre), random_error(rng)
        pose, covariance = window.add(T, error)
        reference.append(T, error)
        want_pose = reference.mean()
        inliers = reference.inliers()
        want_error = reference_mean_error(reference.payloads(inliers), one_draw=True)
        assert window.inliers() == inliers
        assert same_bits(pose, want_pose) and same_bits(window.mean(), want_pose)
        assert same_bits(covariance, want_error.covariance(joint))
        assert_same_error(window.mean_error(), want_error)
        every = {s for e in reference.payloads() for s in e.J}
        assert sorted(window.references()) == sorted(every)
        for got, want in zip(window.payloads(), reference.payloads(), strict=True):
            assert_same_error(got, want)


def test_one_sample_is_its_own_mean():
    rng = np.random.default_rng(0)
    joint = random_joint(rng, KEYS)
    error = random_error(rng)
    error.Q[0, 1] = -0.0
    window = SettlingWindow(5, joint=joint)
    T = np.eye(4)
    pose, covariance = window.add(T, error)
    assert same_bits(pose, T)
    assert same_bits(covariance, error.covariance(joint))
    assert_same_error(window.mean_error(), error)


def test_bad_samples_are_refused_before_anything_is_stored():
    window = SettlingWindow(2)
    with pytest.raises(TypeError, match="LinearError"):
        window.add(np.eye(4), None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="4x4"):
        window.add(np.eye(3), LinearError())
    assert len(window) == 0
    window.add(np.eye(4), LinearError())
    window.append(np.eye(4).tolist(), LinearError())  # append is add without its results
    assert window.full
    with pytest.raises(ValueError, match="already holds 2"):
        window.add(np.eye(4), LinearError())
    assert len(window) == 2
