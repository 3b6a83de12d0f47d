"""The planar PnP solver's hot kernels give, bit for bit, what the code they replace gave.

``_cost_and_normal_equations`` keeps its sums in registers instead of the output arrays,
and ``spd_inverse`` factorises once for its six columns instead of once per column; the
references below are those earlier versions, written in plain Python floats (the same
IEEE operations in the same order as the compiled code, which contracts no products into
fused multiply-adds), so any change of arithmetic shows as a differing bit.
"""

import numpy as np
import pytest

from moma_env.camera import planar_pnp
from moma_env.geometry import make_transform, rotvec_to_matrix


def reference_cost_and_normal_equations(R, t, obj, img, W, prior):
    """The earlier kernel: ``J^T J`` and ``J^T r`` summed corner by corner into the arrays."""
    jtj = [[0.0] * 6 for _ in range(6)]
    jtr = [0.0] * 6
    cost = 0.0
    R = [[float(v) for v in row] for row in R]
    t = [float(v) for v in t]
    for i in range(obj.shape[0]):
        X, Y = float(obj[i, 0]), float(obj[i, 1])
        q0 = R[0][0] * X + R[0][1] * Y
        q1 = R[1][0] * X + R[1][1] * Y
        q2 = R[2][0] * X + R[2][1] * Y
        iz = 1.0 / (q2 + t[2])
        u = (q0 + t[0]) * iz
        v = (q1 + t[1]) * iz
        du = u - float(img[i, 0])
        dv = v - float(img[i, 1])
        w0, w1, w2, w3 = (float(w) for w in W[i])
        ru = w0 * du + w1 * dv
        rv = w2 * du + w3 * dv
        cost += ru * ru + rv * rv
        a2 = -u * iz
        b2 = -v * iz
        ju = [a2 * q1, iz * q2 - a2 * q0, -iz * q1, iz, 0.0, a2]
        jv = [-iz * q2 + b2 * q1, -b2 * q0, iz * q0, 0.0, iz, b2]
        for a in range(6):
            ja, jb = ju[a], jv[a]
            ju[a] = w0 * ja + w1 * jb
            jv[a] = w2 * ja + w3 * jb
        for a in range(6):
            jtr[a] += ju[a] * ru + jv[a] * rv
            for b in range(a, 6):
                jtj[a][b] += ju[a] * ju[b] + jv[a] * jv[b]
    lam = float(prior[0])
    if lam > 0.0:
        p = [float(x) for x in prior]
        uu = [R[i][0] * p[1] + R[i][1] * p[2] + R[i][2] * p[3] for i in range(3)]
        c0, c1, c2 = p[4], p[5], p[6]
        g = [lam * (c1 * uu[2] - c2 * uu[1]), lam * (c2 * uu[0] - c0 * uu[2]), lam * (c0 * uu[1] - c1 * uu[0])]
        cost += g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
        dot = c0 * uu[0] + c1 * uu[1] + c2 * uu[2]
        G = [[lam * ((dot if i == j else 0.0) - uu[i] * p[4 + j]) for j in range(3)] for i in range(3)]
        for a in range(3):
            for i in range(3):
                jtr[a] += G[i][a] * g[i]
            for b in range(a, 3):
                jtj[a][b] += G[0][a] * G[0][b] + G[1][a] * G[1][b] + G[2][a] * G[2][b]
    for a in range(6):
        for b in range(a):
            jtj[a][b] = jtj[b][a]
    return cost, np.array(jtj), np.array(jtr)


def reference_spd_inverse(A):
    """The earlier ``spd_inverse``: each column solved with a Cholesky factorisation of its own."""
    n = A.shape[0]
    out = np.empty((n, n))
    for j in range(n):
        L = [[float(v) for v in row] for row in A]
        b = [1.0 if i == j else 0.0 for i in range(n)]
        for c in range(n):
            d = L[c][c]
            for k in range(c):
                d -= L[c][k] * L[c][k]
            if not d > 0.0:
                return None
            d = float(np.sqrt(d))
            L[c][c] = d
            for i in range(c + 1, n):
                s = L[i][c]
                for k in range(c):
                    s -= L[i][k] * L[c][k]
                L[i][c] = s / d
        for i in range(n):
            s = b[i]
            for k in range(i):
                s -= L[i][k] * b[k]
            b[i] = s / L[i][i]
        for i in range(n - 1, -1, -1):
            s = b[i]
            for k in range(i + 1, n):
                s -= L[k][i] * b[k]
            b[i] = s / L[i][i]
        out[:, j] = b
    for i in range(n):
        for j in range(i):
            m = 0.5 * (out[i, j] + out[j, i])
            out[i, j] = m
            out[j, i] = m
    return out


def random_view(rng):
    """A board of 4-16 corners (m, board plane), seen from 0.5-6 m, its normalised image
    coordinates with noise, per-corner 2x2 weights near ``diag(fx, fy)``, and a prior."""
    n = int(rng.integers(4, 17))
    obj = np.ascontiguousarray(rng.uniform(-0.2, 0.2, size=(n, 2)))
    R = rotvec_to_matrix(rng.normal(scale=0.6, size=3))
    t = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.5, 6.0)])
    q = obj @ R[:, :2].T + t
    img = np.ascontiguousarray(q[:, :2] / q[:, 2:] + rng.normal(scale=2e-3, size=(n, 2)))
    W = np.ascontiguousarray(np.tile([600.0, 0.0, 0.0, 610.0], (n, 1)) + rng.normal(scale=5.0, size=(n, 4)))
    up_m = rng.normal(size=3)
    up_c = rng.normal(size=3)
    lam = 0.0 if rng.random() < 0.5 else float(rng.uniform(1.0, 100.0))
    prior = planar_pnp.prior_vector(lam, up_m / np.linalg.norm(up_m), up_c / np.linalg.norm(up_c))
    start = make_transform(rotvec_to_matrix(rng.normal(scale=0.05, size=3)) @ R, t + rng.normal(scale=0.02, size=3))
    return obj, img, W, prior, start


@pytest.mark.parametrize("seed", range(4))
def test_normal_equations_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for _ in range(50):
        obj, img, W, prior, start = random_view(rng)
        R = np.ascontiguousarray(start[:3, :3])
        t = np.ascontiguousarray(start[:3, 3])
        jtj = np.full((6, 6), np.nan)
        jtr = np.full(6, np.nan)
        cost = planar_pnp._cost_and_normal_equations(R, t, obj, img, W, prior, jtj, jtr)
        want_cost, want_jtj, want_jtr = reference_cost_and_normal_equations(R, t, obj, img, W, prior)
        assert cost == want_cost
        assert jtj.tobytes() == want_jtj.tobytes()
        assert jtr.tobytes() == want_jtr.tobytes()


@pytest.mark.parametrize("seed", range(4))
def test_spd_inverse_bit_for_bit(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(50):
        obj, img, W, prior, start = random_view(rng)
        info = np.empty((6, 6))
        planar_pnp.pose_information(start, obj, img, W, prior, info)
        out = np.empty((6, 6))
        assert planar_pnp.spd_inverse(info, out)
        assert out.tobytes() == reference_spd_inverse(info).tobytes()


def test_spd_inverse_refuses_what_is_not_positive_definite():
    A = np.diag([1.0, 2.0, 3.0, -1.0, 5.0, 6.0])
    out = np.zeros((6, 6))
    assert not planar_pnp.spd_inverse(A, out)
    assert np.isnan(out).all()
    assert reference_spd_inverse(A) is None
