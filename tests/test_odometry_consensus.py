"""The visual odometry's compiled RANSAC consensus against the plain numpy form it replaces."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.geometry import fit_rigid_2d
from moma_env.odometry.visual import _residual_sq, _two_point_consensus


def reference_consensus(p, q, valid, pairs, threshold_sq):
    """RANSAC over two-point samples written with numpy and fit_rigid_2d (the original form)."""
    best = np.zeros(len(p), dtype=bool)
    for a, b in pairs:
        if a == b:
            continue
        if np.sum((q[a] - q[b]) ** 2) < 4.0 * threshold_sq:
            continue
        pair = np.array([a, b])
        inliers = valid & (_residual_sq(p, q, fit_rigid_2d(p[pair], q[pair])) <= threshold_sq)
        if np.count_nonzero(inliers) > np.count_nonzero(best):
            best = inliers
    return best


@pytest.mark.parametrize("seed", range(40))
def test_compiled_consensus_matches_the_numpy_form_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 300))
    q = rng.uniform(-0.3, 0.3, (n, 2))
    yaw, t = rng.normal(0.0, 0.05), rng.normal(0.0, 0.01, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    p = q @ np.array([[c, s], [-s, c]]) + t + rng.normal(0.0, 0.002, (n, 2))  # p = R q + t, noisy
    outliers = rng.random(n) < rng.uniform(0.0, 0.7)
    p[outliers] += rng.uniform(-0.05, 0.05, (int(outliers.sum()), 2))
    q[rng.random(n) < 0.05] = q[0]  # coincident points: pairs too close to fix a rotation
    valid = rng.random(n) < 0.9
    index = np.flatnonzero(valid) if valid.any() else np.arange(n)
    pairs = index[rng.integers(0, len(index), size=(60, 2))]
    threshold_sq = float(rng.choice([0.004, 0.001, 0.02])) ** 2
    expected = reference_consensus(p, q, valid, pairs, threshold_sq)
    found = _two_point_consensus(p, q, valid, pairs, threshold_sq)
    assert found.dtype == bool and np.array_equal(found, expected)
    if seed == 0:
        assert expected.sum() > n // 4  # the data do have a consensus
