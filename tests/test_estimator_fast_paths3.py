"""The estimator's third round of fast paths give the bits of the code they replaced.

:func:`~moma_env.estimator.uncertainty.covariance_one_kernel` (the one-reference case of
:meth:`LinearError.covariance`) must give exactly what :func:`covariance_kernel` gave on
the operands stacked C-ordered, for Jacobians and joint blocks in any memory order, and
:meth:`LinearError.of_packed` exactly the error the ``dict(zip(...))`` it replaced built.
"""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.estimator.uncertainty import LinearError, covariance_kernel, covariance_one_kernel, pack_operands_kernel


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def reference_one_covariance(J: np.ndarray, block: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The replaced code of ``LinearError.covariance`` for one reference."""
    return covariance_kernel(np.ascontiguousarray(J)[None], np.ascontiguousarray(block)[None], Q)


def in_order(M: np.ndarray, order: str) -> np.ndarray:
    if order == "C":
        return np.ascontiguousarray(M)
    if order == "F":
        return np.asfortranarray(M)
    big = np.zeros((12, 12))  # a strided view
    big[::2, ::2] = M
    return big[::2, ::2]


@pytest.mark.parametrize("seed", range(4))
def test_the_one_reference_covariance_kernel_is_the_stacked_one_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for trial in range(60):
        J = rng.normal(size=(6, 6)) * 10.0 ** rng.integers(-3, 3)
        L = rng.normal(size=(6, 6))
        block = L @ L.T if trial % 3 else rng.normal(size=(6, 6))
        Q = rng.normal(size=(6, 6)) * 1e-4
        if trial % 5 == 0:
            Q = -0.0 * Q  # -0.0 entries
        for j_order in ("C", "F", "A"):
            for b_order in ("C", "F", "A"):
                Jx, Bx = in_order(J, j_order), in_order(block, b_order)
                assert same_bits(covariance_one_kernel(Jx, Bx, Q), reference_one_covariance(Jx, Bx, Q))


@pytest.mark.parametrize("seed", range(3))
def test_linear_error_covariance_with_one_reference_is_the_stacked_kernel_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        J = rng.normal(size=(6, 6))
        C = rng.normal(size=(6, 6))
        P = {("a", "a"): C @ C.T, ("a", 1): rng.normal(size=(6, 6))}
        error = LinearError({"a": J}, rng.normal(size=(6, 6)) * 1e-3)
        assert same_bits(error.covariance(P), reference_one_covariance(J, P[("a", "a")], error.Q))
        F = LinearError({"a": np.asfortranarray(J)}, error.Q)
        P[("a", "a")] = np.asfortranarray(P[("a", "a")])
        assert same_bits(F.covariance(P), reference_one_covariance(J, P[("a", "a")], error.Q))


@pytest.mark.parametrize("n_keys", range(4))
def test_of_packed_builds_the_error_the_replaced_code_built(n_keys):
    rng = np.random.default_rng(n_keys)
    keys = [["a"], ["a", 2], [3, "b", 7]][n_keys - 1] if n_keys else []
    for has_P in (False, True):
        Js = rng.normal(size=(n_keys, 6, 6))
        packed = pack_operands_kernel(Js, rng.normal(size=(6, 6)), rng.normal(size=(6, 6)))
        got = LinearError.of_packed(tuple(keys), packed, has_P)
        k = len(keys)
        want = LinearError._of(dict(zip(keys, packed)), packed[k], packed[k + 1] if has_P else None)
        assert type(got) is LinearError
        assert list(got.J) == list(want.J)
        assert all(same_bits(got.J[s], want.J[s]) and np.shares_memory(got.J[s], packed) for s in keys)
        assert same_bits(got.Q, want.Q) and np.shares_memory(got.Q, packed)
        assert (got.P is None) == (want.P is None)
        assert got.P is None or (same_bits(got.P, want.P) and np.shares_memory(got.P, packed))


def random_check_inputs(rng: np.random.Generator):
    """Poses and covariances on both sides of the fast checks' limits."""
    from moma_env import geometry as g

    for trial in range(300):
        T = g.make_transform(g.rotvec_to_matrix(rng.normal(0.0, 2.0, 3)), rng.normal(0.0, 3.0, 3))
        kind = trial % 6
        if kind == 1:
            T[rng.integers(0, 4), rng.integers(0, 4)] += rng.normal(0.0, 1e-6)  # near the tolerance
        elif kind == 2:
            T[rng.integers(0, 4), rng.integers(0, 4)] = (np.nan, np.inf, -np.inf)[trial % 3]
        elif kind == 3:
            T[:3, :3] = -T[:3, :3]  # determinant -1
        elif kind == 4:
            T[3] = (0.0, 0.0, rng.normal(0.0, 1e-6), 1.0)
        L = rng.normal(0.0, 0.01, (6, 6))
        cov = L @ L.T
        ckind = (trial // 6) % 5
        if ckind == 1:
            cov[0, 1] += rng.normal(0.0, 1e-9)  # asymmetric near the limit
        elif ckind == 2:
            cov[2, 2] = -abs(cov[2, 2]) - 1e-12
        elif ckind == 3:
            cov[rng.integers(0, 6), rng.integers(0, 6)] = np.nan
        yield T, cov


def test_one_call_of_both_fast_checks_is_the_two_checks():
    from moma_env.estimator import moma as moma_module

    rng = np.random.default_rng(11)
    seen = set()
    for T, cov in random_check_inputs(rng):
        failed = moma_module._failed_fast_checks_kernel(
            T, cov, moma_module._CLEAR_ROTATION_TOLERANCE, moma_module._ROTATION_TOLERANCE
        )
        want = (0 if moma_module._clearly_rigid(T) else 1) + (0 if moma_module._clearly_valid_covariance(cov) else 2)
        assert failed == want
        seen.add(want)
    assert seen == {0, 1, 2, 3}
