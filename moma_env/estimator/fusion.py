"""Information-weighted fusion of several estimates of one pose.

The paper fuses the poses a camera gets from several reference boards, and the
poses a robot gets from several cameras, by an unweighted mean. Here each
candidate ``T_i`` (4x4, in W) with error ``e_i`` (a
:class:`~moma_env.estimator.uncertainty.LinearError`, covariance ``P_i``, the
convention of :mod:`moma_env.estimator.uncertainty`: translation (m) first, then
rotation (rad), perturbed on the left in W) is weighted by its information::

    W_i = (sum_j P_j^-1)^-1 P_i^-1          (6x6, sum_i W_i = I)
    T   = T_0 (+) sum_i W_i (T_i (-) T_0)    (iterated to the weighted mean)
    e   = sum_i W_i e_i

The fused error keeps every candidate's dependence on the frozen references
(the weights ignore the correlations the candidates share through a common
reference, so the weighting is then not optimal, but the reported covariance is
still that of the fused pose to first order). Candidates whose covariance is
singular (an upright robot has no error in height, roll and pitch) get a
regularisation of ``1e-9`` times the largest variance on the diagonal, so that
those components are averaged evenly; with every covariance zero (exact
measurements) the fusion is the unweighted mean in the tangent space.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from moma_env.estimator.uncertainty import LinearError, apply_error, pose_error

__all__ = ["information_weights", "information_fusion"]

#: Regularisation of the covariances, relative to the largest variance.
_RELATIVE_FLOOR = 1e-9
#: Iterations of the weighted mean on the manifold (it converges quadratically).
_ITERATIONS = 3


def information_weights(covariances: Sequence[np.ndarray]) -> list[np.ndarray]:
    """The 6x6 weights ``W_i = (sum_j P_j^-1)^-1 P_i^-1`` of candidates of covariances ``P_i``.

    Raises:
        ValueError: no covariance, or one that is not a finite 6x6 array.
    """
    if not covariances:
        raise ValueError("information_weights needs at least one covariance")
    covs = [np.asarray(P, dtype=float) for P in covariances]
    for i, P in enumerate(covs):
        if P.shape != (6, 6) or not np.isfinite(P).all():
            raise ValueError(f"covariances[{i}] must be a finite 6x6 array, got shape {P.shape}")
    largest = max(float(np.max(np.diag(P))) for P in covs)
    floor = _RELATIVE_FLOOR * largest if largest > 0.0 else 1.0
    eye = np.eye(6)
    infos = [np.linalg.inv(P + floor * eye) for P in covs]
    total = np.linalg.inv(sum(infos))
    return [total @ info for info in infos]


def information_fusion(
    poses: Sequence[np.ndarray], errors: Sequence[LinearError], joint: Mapping
) -> tuple[np.ndarray, LinearError]:
    """The information-weighted mean of ``poses`` (4x4 in W) and its error.

    Args:
        poses: the candidates.
        errors: their errors, in the same order.
        joint: the joint covariance of the frozen references' errors
            (``P[(s, r)]``), which gives each candidate's covariance.
    """
    if len(poses) != len(errors) or not poses:
        raise ValueError(f"information_fusion needs as many errors as poses (>= 1), got {len(poses)} and {len(errors)}")
    if len(poses) == 1:
        return np.array(poses[0], dtype=float), errors[0]
    weights = information_weights([e.covariance(joint) for e in errors])
    T = np.array(poses[0], dtype=float)
    for _ in range(_ITERATIONS):
        step = sum(W @ pose_error(P, T) for W, P in zip(weights, poses))
        T = apply_error(T, step)
    J: dict = {}
    Q = np.zeros((6, 6))
    P = None  # the persistent part of the fresh noise (the candidates' are independent of each other)
    for W, e in zip(weights, errors):
        for key, Jk in e.J.items():
            J[key] = J[key] + W @ Jk if key in J else W @ Jk
        Q += W @ e.Q @ W.T
        if e.P is not None:
            P = W @ e.P @ W.T if P is None else P + W @ e.P @ W.T
    return T, LinearError(J, 0.5 * (Q + Q.T), None if P is None else 0.5 * (P + P.T))
