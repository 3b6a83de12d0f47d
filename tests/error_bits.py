"""Test helper: arrays and first-order errors compared bit for bit."""

import numpy as np

from moma_env.estimator.uncertainty import LinearError


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Same shape, dtype and bytes (so -0.0 differs from 0.0, and NaNs by their payload)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def assert_same_error(got: LinearError, want: LinearError) -> None:
    """The same references in the same order, and the same bits of every Jacobian, ``Q`` and ``P``."""
    assert list(got.J) == list(want.J)
    assert all(same_bits(got.J[s], want.J[s]) for s in got.J)
    assert same_bits(got.Q, want.Q)
    assert (got.P is None) == (want.P is None)
    if got.P is not None:
        assert same_bits(got.P, want.P)


def random_joint(rng: np.random.Generator, keys: list) -> dict:
    """A joint covariance of the references ``keys`` as the estimator keeps it: ``(s, s)``
    symmetric positive semi-definite, ``(s, r)`` and ``(r, s)`` transposed."""
    joint = {}
    for i, s in enumerate(keys):
        A = rng.normal(size=(6, 6))
        joint[(s, s)] = A @ A.T
        for r in keys[:i]:
            C = rng.normal(size=(6, 6))
            joint[(s, r)], joint[(r, s)] = C, C.T
    return joint
