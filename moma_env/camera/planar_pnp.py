"""Batched PnP for planar targets: homography DLT, both planar poses, Gauss-Newton.

Solves K independent problems at once: board k has n points ``(X, Y)`` on the
plane ``z = 0`` of its frame M and their undistorted normalised image coordinates
``(x, y) = (X_c / Z_c, Y_c / Z_c)`` in the camera frame C (OpenCV: x right, y
down, z along the optical axis). The result is the pose ``T_c_m`` that minimises
the sum of squared normalised reprojection errors, found in four steps, each a
handful of numpy operations over all boards:

1. Homography DLT (``h33 = 1``) from the point moments, one 8x8 solve per board.
   The model is expressed about the weighted centroid of the points, whose depth
   is positive, so ``h33 = 1`` is a valid normalisation.
2. Pose from the homography: the polar factor of its first two columns gives
   ``r1, r2``, their mean singular value the scale of ``t``. A planar target has
   two poses that explain the image almost equally well when it is small or seen
   nearly face-on (the ambiguity IPPE resolves by keeping both); the second one
   is the first reflected through the plane orthogonal to the line of sight to
   the centroid: ``[r1 r2]' = S [r1 r2]``, ``t' = t``, ``S = I - 2 v v^T``.
3. Gauss-Newton on both candidates: each iteration solves a 6x6 system per
   candidate (rotation increment in the camera frame, then translation) built
   from second moments of nine per-point features, and applies the rotation
   increment as a Cayley (unit quaternion) rotation, so the pose stays exactly
   rigid.
4. The candidate with the lower cost wins.

Without noise the DLT is exact and Gauss-Newton keeps the pose exact (to ~1e-12);
with noise the result is the least-squares (maximum-likelihood for Gaussian
noise on normalised coordinates) pose, the one OpenCV's SOLVEPNP_ITERATIVE
refines to. Problems whose normal equations are singular (degenerate points) come
out as NaN poses; callers drop them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["solve_planar_pnp", "PLANAR_GN_ITERATIONS"]

#: Gauss-Newton iterations run on both candidate poses.
PLANAR_GN_ITERATIONS = 2


def _constants() -> dict[str, np.ndarray]:
    """Constant matrices of the solver (read-only), built once at import."""
    # DLT rows of a point, a1 = [X, Y, 1, 0, 0, 0, -xX, -xY | x] and
    # a2 = [0, 0, 0, X, Y, 1, -yX, -yY | y], are linear in the moment features
    # w = [X, Y, 1, xX, xY, x, yX, yY, y]: a1 = A1 @ w, a2 = A2 @ w.
    A1 = np.zeros((9, 9))
    A2 = np.zeros((9, 9))
    for row, col, sign in ((0, 0, 1), (1, 1, 1), (2, 2, 1), (6, 3, -1), (7, 4, -1), (8, 5, 1)):
        A1[row, col] = sign
    for row, col, sign in ((3, 0, 1), (4, 1, 1), (5, 2, 1), (6, 6, -1), (7, 7, -1), (8, 8, 1)):
        A2[row, col] = sign
    # Sum of a a^T over both rows = A1 (w w^T) A1^T + A2 (w w^T) A2^T: (81,) -> (81,) linear map,
    # keeping the 8 rows of the normal equations (8x8 matrix and right-hand side): (81, 72).
    dlt = np.einsum("ia,jb->abij", A1, A1) + np.einsum("ia,jb->abij", A2, A2)
    dlt = dlt.reshape(81, 9, 9)[:, :8, :].reshape(81, 72)

    # Gauss-Newton: features f = [1, x, y, x^2, xy, y^2, 1/z, x/z, y/z] of a point at
    # normalised (x, y) and depth z. Perturbing the pose as p_c -> p_c + w x p_c + v
    # (w, v in C), the Jacobian rows of (x, y) with respect to (u, v), u = w / 2, are
    # Jx = [-2xy, 2(1 + x^2), -2y, 1/z, 0, -x/z] and Jy = [-2(1 + y^2), 2xy, 2x, 0, 1/z, -y/z],
    # linear in f: Jx = f @ Cx, Jy = f @ Cy.
    Cx = np.zeros((9, 6))
    Cy = np.zeros((9, 6))
    for feat, col, value in ((4, 0, -2), (0, 1, 2), (3, 1, 2), (2, 2, -2), (6, 3, 1), (7, 5, -1)):
        Cx[feat, col] = value
    for feat, col, value in ((0, 0, -2), (5, 0, -2), (4, 1, 2), (1, 2, 2), (6, 4, 1), (8, 5, -1)):
        Cy[feat, col] = value
    # J^T J = Cx^T (f f^T) Cx + Cy^T (f f^T) Cy and -J^T r = -(Cx^T f rx + Cy^T f ry).
    hessian = (np.einsum("ai,bj->abij", Cx, Cx) + np.einsum("ai,bj->abij", Cy, Cy)).reshape(81, 36)
    gradient = -np.stack([Cx, Cy], axis=1).reshape(18, 6)

    # Cayley rotation of u: with q = (1, u), R = [(1 - |u|^2) I + 2 u u^T + 2 [u]x] / (1 + |u|^2);
    # the numerator is linear in q q^T: (16,) -> (9,).
    cayley = np.zeros((4, 4, 3, 3))
    eye = np.eye(3)
    cayley[0, 0] = eye
    for i in range(3):
        cayley[1 + i, 1 + i] -= eye
        for j in range(3):
            cayley[1 + i, 1 + j, i, j] += 2.0
        skew = np.cross(eye[i], eye)  # rows e_i x e_j, i.e. columns of [e_i]x transposed
        cayley[0, 1 + i] += skew.T
        cayley[1 + i, 0] += skew.T
    cayley = cayley.reshape(16, 9)

    # Cross product: (a outer b).ravel() @ cross = a x b.
    levi = np.zeros((3, 3, 3))
    levi[0, 1, 2] = levi[1, 2, 0] = levi[2, 0, 1] = 1.0
    levi[0, 2, 1] = levi[2, 1, 0] = levi[1, 0, 2] = -1.0
    cross = levi.transpose(1, 2, 0).reshape(9, 3)

    out = {"dlt": dlt, "hessian": hessian, "gradient": gradient, "cayley": cayley, "cross": cross, "eye": eye}
    for a in out.values():
        a.setflags(write=False)
    return out


_C = _constants()


def solve_planar_pnp(
    model_xy: np.ndarray,
    image_xy: np.ndarray,
    weights: np.ndarray | None = None,
    iterations: int = PLANAR_GN_ITERATIONS,
) -> tuple[np.ndarray, np.ndarray]:
    """Poses of K planar targets from n point correspondences each.

    Args:
        model_xy: (K, 2, n) rows X and Y (m) of the points on the plane z = 0 of
            each target's frame M.
        image_xy: (K, 2, n) rows x and y of their undistorted normalised image
            coordinates.
        weights: optional (K, n) non-negative point weights (0 drops a point, to
            pad targets with fewer points); each target needs at least four
            points of positive weight, no three of them collinear.
        iterations: Gauss-Newton iterations (>= 1).

    Returns:
        ``(T_c_m, cost)``: (K, 4, 4) poses of M in C and the (K,) weighted sum of
        squared normalised residuals at them. Degenerate problems give NaN.
    """
    K, _, n = model_xy.shape
    if weights is None:
        centroid = np.add.reduce(model_xy, axis=2) / n
    else:
        centroid = np.matmul(model_xy, weights[:, :, None])[:, :, 0] / np.add.reduce(weights, axis=1)[:, None]
    # Homogeneous model points about the centroid: rows X, Y, 1 -> (K, 3, n).
    g = np.empty((K, 3, n))
    np.subtract(model_xy, centroid[:, :, None], out=g[:, :2])
    g[:, 2] = 1.0

    # 1. DLT from the moments of w = [g, x g, y g] (K, 9, n).
    w = np.empty((K, 9, n))
    w[:, 0:3] = g
    np.multiply(g, image_xy[:, 0:1], out=w[:, 3:6])
    np.multiply(g, image_xy[:, 1:2], out=w[:, 6:9])
    wt = w.transpose(0, 2, 1) if weights is None else (w * weights[:, None, :]).transpose(0, 2, 1)
    normal = np.matmul(np.matmul(w, wt).reshape(K, 81), _C["dlt"]).reshape(K, 8, 9)
    H = np.empty((K, 9))
    H[:, :8] = np.linalg.solve(normal[:, :, :8], normal[:, :, 8:])[:, :, 0]
    H[:, 8] = 1.0
    H = H.reshape(K, 3, 3)

    # 2. Pose from the homography, and its mirror twin: P = [r1 r2 t], (2, K, 3, 3).
    U, s, Vt = np.linalg.svd(H[:, :, :2], full_matrices=False)
    P = np.empty((2, K, 3, 3))
    np.matmul(U, Vt, out=P[0, :, :, :2])
    np.multiply(H[:, :, 2], (2.0 / (s[:, 0] + s[:, 1]))[:, None], out=P[0, :, :, 2])
    t = P[0, :, :, 2]
    reflect = t[:, :, None] * t[:, None, :]
    reflect *= (-2.0 / np.add.reduce(t * t, axis=1))[:, None, None]
    reflect += _C["eye"]
    np.matmul(reflect, P[0], out=P[1])
    P[1, :, :, 2] = t

    # 3. Gauss-Newton on both candidates.
    f = np.empty((2, K, 9, n))
    f[:, :, 0] = 1.0
    ft = f.transpose(0, 1, 3, 2)
    fw = f if weights is None else None
    q = np.empty((2, K, 4))
    q[:, :, 0] = 1.0
    for _ in range(iterations):
        pc = np.matmul(P, g)
        np.divide(1.0, pc[:, :, 2], out=f[:, :, 6])
        np.multiply(pc[:, :, :2], f[:, :, 6:7], out=f[:, :, 1:3])
        np.multiply(f[:, :, 1:3], f[:, :, 1:2], out=f[:, :, 3:5])
        np.multiply(f[:, :, 2], f[:, :, 2], out=f[:, :, 5])
        np.multiply(f[:, :, 1:3], f[:, :, 6:7], out=f[:, :, 7:9])
        res = f[:, :, 1:3] - image_xy
        if weights is not None:
            fw = f * weights[:, None, :]
        moments = np.matmul(fw, ft).reshape(2, K, 81)
        rhs = np.matmul(fw, res.transpose(0, 1, 3, 2)).reshape(2, K, 18)
        step = np.linalg.solve(
            np.matmul(moments, _C["hessian"]).reshape(2, K, 6, 6), np.matmul(rhs, _C["gradient"])[..., None]
        )[..., 0]
        q[:, :, 1:] = step[:, :, :3]
        qq = q[:, :, :, None] * q[:, :, None, :]
        rot = np.matmul(qq.reshape(2, K, 16), _C["cayley"]).reshape(2, K, 3, 3)
        rot /= np.add.reduce(q * q, axis=2)[:, :, None, None]
        P = np.matmul(rot, P)
        P[:, :, :, 2] += step[:, :, 3:]

    # 4. Cost of both candidates; keep the better one.
    pc = np.matmul(P, g)
    res = pc[:, :, :2] / pc[:, :, 2:3]
    res -= image_xy
    res *= res
    sq = np.add.reduce(res, axis=2)
    if weights is not None:
        sq *= weights
    cost = np.add.reduce(sq, axis=2)
    cost[~(pc[:, :, 2] > 0.0).all(axis=2)] = np.inf  # a pose with points behind the camera loses
    second = cost[1] < cost[0]
    best = np.where(second[:, None, None], P[1], P[0])
    T = np.zeros((K, 4, 4))
    T[:, :3, :2] = best[:, :, :2]
    T[:, :3, 2] = np.matmul((best[:, :, 0, None] * best[:, None, :, 1]).reshape(K, 9), _C["cross"])
    # Translation of the model origin: t_M = t_centroid - R @ centroid.
    T[:, :3, 3] = best[:, :, 2] - np.matmul(best[:, :, :2], centroid[:, :, None])[:, :, 0]
    T[:, 3, 3] = 1.0
    return T, np.where(second, cost[1], cost[0])
