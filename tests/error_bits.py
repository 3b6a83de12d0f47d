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


def reference_mean_error(errors: list[LinearError], one_draw: bool = False) -> LinearError:
    """The error of the mean of estimates with these errors, in plain numpy: Jacobians and
    fresh noise averaged, the noises independent; persistent parts ``P`` one draw when
    ``one_draw`` (a switch window's samples: ``(Q + (n - 1) P) / n^2`` and ``P / n``), else
    independent too (``Q / n^2``, ``P / n^2``). One error is its own mean."""
    n = len(errors)
    if n == 1:
        return errors[0]
    J: dict = {}
    Q = np.zeros((6, 6))
    P = None
    for e in errors:
        for s, Js in e.J.items():
            J[s] = J[s] + Js if s in J else Js.copy()
        Q += e.Q
        if e.P is not None:
            P = e.P.copy() if P is None else P + e.P
    mean_J = {s: Js / n for s, Js in J.items()}
    if P is None:
        return LinearError(mean_J, Q / (n * n))
    if one_draw:
        return LinearError(mean_J, (Q + (n - 1) * P) / (n * n), P / n)
    return LinearError(mean_J, Q / (n * n), P / (n * n))
