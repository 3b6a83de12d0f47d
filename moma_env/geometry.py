"""Rigid-body transforms in SE(2) and SE(3), and pose averaging.

Conventions (pinned by ``tests/test_geometry.py``):

* ``T_a_b`` is the 4x4 homogeneous pose of frame ``b`` expressed in frame ``a``,
  so a point maps as ``p_a = T_a_b @ p_b`` and poses chain as
  ``T_a_c = T_a_b @ T_b_c``.
* Planar poses are ``(x, y, yaw)`` in metres and radians; ``yaw`` is the rotation
  about +z, counter-clockwise seen from above. ``se2_to_se3(x, y, yaw, z)`` lifts a
  planar pose to a 3D pose at height ``z``.
* Rotations ``rot_x/rot_y/rot_z`` are active, right-handed rotations about the
  named axis.
* World W: x, y on the floor, z up. Robot body B: x forward, y left, z up.
  Board M (OpenCV ArUco object frame): origin at the board centre, x to the right
  and y up on the printed face, z out of the printed face. Camera C (OpenCV):
  x right, y down, z along the optical axis.

All functions are pure and allocate new arrays; none keeps state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba
import numpy as np

_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
# The 4x4 identity se2_to_se3 copies and fills in (read-only: shared, never written).
_SE3_IDENTITY = np.eye(4)
_SE3_IDENTITY.setflags(write=False)

__all__ = [
    "wrap_angle",
    "hypot_kernel",
    "rot_x",
    "rot_y",
    "rot_z",
    "make_transform",
    "invert",
    "invert_kernel",
    "pose_array",
    "kernel_array",
    "translation",
    "rotation",
    "se2_to_se3",
    "set_planar",
    "se3_to_se2",
    "yaw_of",
    "rotation_angle",
    "upright_body_from_mount",
    "upright_body_kernel",
    "mount_rotation_kernel",
    "rotvec_to_matrix",
    "matrix_to_rotvec",
    "matrix_to_quaternion",
    "project_to_rotation",
    "polar_rotation_kernel",
    "mean_rotation",
    "mean_pose",
    "interpolate_pose",
    "fit_rigid_2d",
    "R_BODY_CAM_DOWN",
    "R_BODY_CAM_FORWARD",
    "R_BODY_BOARD_UP",
    "R_BODY_BOARD_BACK",
    "R_BODY_CAM_BACKWARD",
    "R_BODY_BOARD_FRONT",
]


def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle (rad) to the interval [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


#: Veltkamp's splitting constant, 2**27 + 1, and the smallest normal float64.
_SPLITTER = 134217729.0
_DBL_MIN = 2.2250738585072014e-308


@numba.njit(cache=True)
def _split(x: float) -> tuple[float, float]:
    """``x`` as ``hi + lo``, each with at most 26 significant bits (Dekker, Veltkamp)."""
    t = x * _SPLITTER
    hi = t - (t - x)
    return hi, x - hi


@numba.njit(cache=True)
def _exact_product(x: float, y: float) -> tuple[float, float]:
    """``x * y`` as ``hi + lo`` (Dekker's product)."""
    xh, xl = _split(x)
    yh, yl = _split(y)
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


@numba.njit(cache=True)
def _exact_sum(a: float, b: float) -> tuple[float, float]:
    """``a + b`` as ``hi + lo`` for ``|a| >= |b|`` (Dekker's fast two-sum)."""
    x = a + b
    return x, b - (x - a)


@numba.njit(cache=True)
def hypot_kernel(x: float, y: float) -> float:
    """``math.hypot(x, y)``, compiled, bit for bit: CPython's vector norm (scaled by a power
    of two, squares and sums carried in two floats, a square root with one differential
    correction; the same arithmetic in Python replayed against ``math.hypot`` of CPython
    3.10, 3.11, 3.12 and 3.13 on 600,000 pairs agreed on every one), not the C library's ``hypot``, which differs from it in the
    last bit for about 0.6 % of arguments. Bit for bit where the larger magnitude is a
    normal float (at least 2.2e-308); below that, within one unit of the last place.
    ``tests/test_geometry.py`` compares the two."""
    a = abs(x)
    b = abs(y)
    if math.isinf(a) or math.isinf(b):
        return math.inf
    if math.isnan(a) or math.isnan(b):
        return math.nan
    largest = a if a > b else b
    if largest == 0.0:
        return largest
    scaled_back = 1.0
    _, exponent = math.frexp(largest)
    if exponent < -1023:  # subnormal: normalise first
        a /= _DBL_MIN
        b /= _DBL_MIN
        largest /= _DBL_MIN
        scaled_back = _DBL_MIN
        _, exponent = math.frexp(largest)
    scale = math.ldexp(1.0, -exponent)
    csum = 1.0
    frac1 = 0.0
    frac2 = 0.0
    for v in (a, b):
        v *= scale
        hi, lo = _exact_product(v, v)
        csum, rest = _exact_sum(csum, hi)
        frac1 += lo
        frac2 += rest
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _exact_product(-h, h)
    csum, rest = _exact_sum(csum, hi)
    frac1 += lo
    frac2 += rest
    h += (csum - 1.0 + (frac1 + frac2)) / (2.0 * h)
    return scaled_back * (h / scale)


def rot_x(angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about +x."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about +y."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about +z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def make_transform(R: np.ndarray | None = None, t: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
    """4x4 homogeneous transform from a 3x3 rotation and a translation (m)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform: ``invert(T_a_b) == T_b_a`` (a new array)."""
    return invert_kernel(pose_array(T, "T"))


def pose_array(T: object, name: str) -> np.ndarray:
    """``T`` as a C-ordered float64 4x4 array (itself when it is one), for the compiled
    helpers; ValueError naming ``name`` for another shape."""
    return kernel_array(T, (4, 4), name)


def kernel_array(M: object, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``M`` as a C-ordered float64 array of ``shape`` (itself when it is one), what the
    compiled kernels take; ValueError naming ``name`` for another shape."""
    if type(M) is not np.ndarray or M.dtype.char != "d" or not M.flags.c_contiguous:
        M = np.ascontiguousarray(M, dtype=float)
    if M.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {M.shape}")
    return M


@numba.njit(cache=True)
def invert_kernel(T: np.ndarray) -> np.ndarray:
    """:func:`invert` of a float64 4x4 array, compiled: the arithmetic of numpy's
    ``R.T @ t`` (BLAS, the transposed view as a column-major matrix), bit for bit."""
    Rt = np.asfortranarray(T[:3, :3].T)
    v = np.dot(Rt, np.ascontiguousarray(T[:3, 3]))
    Ti = np.empty((4, 4))
    Ti[:3, :3] = Rt
    Ti[0, 3] = -v[0]
    Ti[1, 3] = -v[1]
    Ti[2, 3] = -v[2]
    Ti[3, 0] = 0.0
    Ti[3, 1] = 0.0
    Ti[3, 2] = 0.0
    Ti[3, 3] = 1.0
    return Ti


def translation(T: np.ndarray) -> np.ndarray:
    """Translation part (m) of a 4x4 transform, as a copy."""
    return T[:3, 3].copy()


def rotation(T: np.ndarray) -> np.ndarray:
    """Rotation part of a 4x4 transform, as a copy."""
    return T[:3, :3].copy()


def set_planar(T: np.ndarray, x: float, y: float, yaw: float) -> None:
    """Write a planar pose (m, m, rad) into a 4x4 pose ``T`` in place: the rotation about z
    in the upper-left 2x2 block and ``x``, ``y`` in the translation; the other entries are
    left as they are (``T`` holds the identity there, or the height of its plane)."""
    c, s = math.cos(yaw), math.sin(yaw)
    T[0, 0] = c
    T[0, 1] = -s
    T[0, 3] = x
    T[1, 0] = s
    T[1, 1] = c
    T[1, 3] = y


def se2_to_se3(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """Lift a planar pose (m, m, rad) to a 4x4 pose at height ``z`` (m)."""
    # A copy of the identity with its seven entries set: the float64 array that
    # np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]) makes, at
    # half the cost (no nested-list shape discovery).
    T = _SE3_IDENTITY.copy()
    set_planar(T, x, y, yaw)
    T[2, 3] = z
    return T


def yaw_of(R_or_T: np.ndarray) -> float:
    """Heading (rad) of the frame's x axis projected on the xy plane."""
    R = R_or_T[:3, :3]
    return math.atan2(R[1, 0], R[0, 0])


def se3_to_se2(T: np.ndarray) -> tuple[float, float, float]:
    """Project a 4x4 pose to the plane: ``(x, y, yaw)`` with yaw of the x axis."""
    # The first two rows read as Python floats at once (the same doubles as T[i, j]):
    # yaw_of's atan2(T[1, 0], T[0, 0]) without four numpy scalar reads.
    row0, row1 = T[:2].tolist()
    return float(row0[3]), float(row1[3]), math.atan2(row1[0], row0[0])


def upright_body_from_mount(T_w_x: np.ndarray, T_b_x: np.ndarray, z: float = 0.0) -> np.ndarray:
    """Pose ``T_w_b`` of an upright body (roll = pitch = 0, height ``z``) from a mounted frame.

    ``T_w_x`` is a measured pose of a frame x (a board or a camera) rigidly mounted
    at ``T_b_x`` on a ground robot. The body's yaw is taken from the measured
    orientation, and its position so that the mount point lands exactly on the
    measured one in x and y. Projecting at the mount rather than at the body
    keeps a small tilt error of the measurement from swinging the body origin
    through the mount's lever arm (a board 0.4 m above the floor tilted by 0.1 rad
    would otherwise move the robot by 4 cm).
    """
    return upright_body_kernel(pose_array(T_w_x, "T_w_x"), pose_array(T_b_x, "T_b_x"), float(z))


@numba.njit(cache=True)
def mount_rotation_kernel(T_w_x: np.ndarray, T_b_x: np.ndarray) -> np.ndarray:
    """``T_w_x[:3, :3] @ T_b_x[:3, :3].T`` (3x3) with numpy's BLAS product, bit for bit."""
    return np.dot(np.ascontiguousarray(T_w_x[:3, :3]), np.asfortranarray(T_b_x[:3, :3].T))


@numba.njit(cache=True)
def upright_body_kernel(T_w_x: np.ndarray, T_b_x: np.ndarray, z: float) -> np.ndarray:
    """:func:`upright_body_from_mount` of float64 4x4 arrays, compiled (the C library's atan2)."""
    R = mount_rotation_kernel(T_w_x, T_b_x)
    yaw = math.atan2(R[1, 0], R[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty = T_b_x[0, 3], T_b_x[1, 3]
    out = np.zeros((4, 4))
    out[0, 0] = c
    out[0, 1] = -s
    out[0, 3] = T_w_x[0, 3] - (c * tx - s * ty)
    out[1, 0] = s
    out[1, 1] = c
    out[1, 3] = T_w_x[1, 3] - (s * tx + c * ty)
    out[2, 2] = 1.0
    out[2, 3] = z
    out[3, 3] = 1.0
    return out


def rotation_angle(R: np.ndarray) -> float:
    """Angle (rad, in [0, pi]) of a rotation matrix."""
    c = (np.trace(R[:3, :3]) - 1.0) / 2.0
    return math.acos(min(1.0, max(-1.0, c)))


def rotvec_to_matrix(rvec: Sequence[float] | np.ndarray) -> np.ndarray:
    """Rodrigues: axis-angle vector (rad) to a 3x3 rotation matrix."""
    r = np.asarray(rvec, dtype=float).reshape(3)
    theta = float(np.linalg.norm(r))
    if theta < 1e-12:
        K = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
        return np.eye(3) + K
    k = r / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Inverse Rodrigues: 3x3 rotation matrix to an axis-angle vector (rad)."""
    q = matrix_to_quaternion(R)  # (x, y, z, w), w >= 0
    v = q[:3]
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        return 2.0 * v
    angle = 2.0 * math.atan2(s, q[3])
    return v / s * angle


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(qx, qy, qz, qw)`` of a rotation matrix, with ``qw >= 0``.

    This is the order of the TUM trajectory format.
    """
    m = R[:3, :3]
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s])
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2.0
        q = np.array([0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s])
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2.0
        q = np.array([(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s])
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2.0
        q = np.array([(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s])
    q /= np.linalg.norm(q)
    if q[3] < 0.0:
        q = -q
    return q


def project_to_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation closest to the 3x3 matrix ``M`` in Frobenius norm (a new array).

    A positive multiple of ``M`` gives the same rotation, so the sum of a set of
    rotation matrices projects to their chordal mean. For ``det(M) > 0`` this is
    the orthogonal polar factor of ``M``, found by a compiled Newton iteration
    (a few microseconds); otherwise, or if the iteration does not converge, by SVD.
    """
    M = np.ascontiguousarray(M, dtype=float)  # C-ordered, whatever it was: one compilation of the kernel
    R = np.empty((3, 3))
    if polar_rotation_kernel(M, R):
        return R
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    (a, b, c), (d, e, f), (g, h, i) = R.tolist()
    if a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) < 0.0:
        U[:, 2] = -U[:, 2]
        R = U @ Vt
    return R


@numba.njit(cache=True)
def polar_rotation_kernel(M: np.ndarray, R: np.ndarray) -> bool:
    """Orthogonal polar factor of a 3x3 ``M`` with ``det(M) > 0``, into ``R``.

    Scaled Newton iteration ``X <- (g X + X^-T / g) / 2`` with the determinant
    scaling ``g = |det X|^(-1/3)`` (Higham); converges quadratically. False when
    ``det(M) <= 0`` (well, not clearly positive) or after 30 iterations.
    """
    X = M.copy()
    for _ in range(30):
        c00 = X[1, 1] * X[2, 2] - X[1, 2] * X[2, 1]
        c01 = X[1, 2] * X[2, 0] - X[1, 0] * X[2, 2]
        c02 = X[1, 0] * X[2, 1] - X[1, 1] * X[2, 0]
        c10 = X[0, 2] * X[2, 1] - X[0, 1] * X[2, 2]
        c11 = X[0, 0] * X[2, 2] - X[0, 2] * X[2, 0]
        c12 = X[0, 1] * X[2, 0] - X[0, 0] * X[2, 1]
        c20 = X[0, 1] * X[1, 2] - X[0, 2] * X[1, 1]
        c21 = X[0, 2] * X[1, 0] - X[0, 0] * X[1, 2]
        c22 = X[0, 0] * X[1, 1] - X[0, 1] * X[1, 0]
        det = X[0, 0] * c00 + X[0, 1] * c01 + X[0, 2] * c02
        if not det > 1e-300:
            return False
        g = det ** (-1.0 / 3.0)
        # X^-T = cofactor matrix / det.
        h = 1.0 / (g * det)
        delta = 0.0
        for i in range(3):
            for j in range(3):
                if i == 0:
                    cof = c00 if j == 0 else (c01 if j == 1 else c02)
                elif i == 1:
                    cof = c10 if j == 0 else (c11 if j == 1 else c12)
                else:
                    cof = c20 if j == 0 else (c21 if j == 1 else c22)
                new = 0.5 * (g * X[i, j] + h * cof)
                delta = max(delta, abs(new - X[i, j]))
                R[i, j] = new
        X[:, :] = R
        if delta < 1e-15:
            return True
    return False


def _checked_stack(poses: Sequence[np.ndarray] | np.ndarray, what: str) -> Sequence[np.ndarray] | np.ndarray:
    if len(poses) == 0:
        raise ValueError(f"{what} needs a non-empty sequence of poses")
    shape = np.shape(poses[0])
    if shape not in ((3, 3), (4, 4)):
        raise ValueError(f"{what} needs 3x3 rotations or 4x4 poses, got shape {shape}")
    return poses


def mean_rotation(rotations: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
    """Chordal L2 mean on SO(3) of a set of rotation matrices (3x3, or 4x4 poses).

    The arithmetic mean of the matrices projected back onto SO(3) with an SVD
    (the rotation closest in Frobenius norm). For rotations spread by less than
    a few degrees, as in a switch window, it agrees with the geodesic (Karcher)
    mean to second order and, unlike an incremental slerp, does not depend on the
    order of the samples.
    """
    _checked_stack(rotations, "mean_rotation")
    total = np.array(rotations[0], dtype=float)[:3, :3]
    for R in rotations[1:]:
        total = total + R[:3, :3]
    return project_to_rotation(total)


def mean_pose(poses: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
    """Average of 4x4 poses: arithmetic mean translation, chordal mean rotation.

    Cheap on a handful of poses (it runs in the estimator's per-frame path).
    """
    _checked_stack(poses, "mean_pose")
    if np.shape(poses[0]) != (4, 4):
        raise ValueError(f"mean_pose needs 4x4 poses, got shape {np.shape(poses[0])}")
    total = np.array(poses[0], dtype=float)
    for T in poses[1:]:
        total += T
    out = np.empty((4, 4))
    out[:3, :3] = project_to_rotation(total[:3, :3])
    out[:3, 3] = total[:3, 3] / len(poses)
    out[3] = _LAST_ROW
    return out



def interpolate_pose(T0: np.ndarray, T1: np.ndarray, fraction: float) -> np.ndarray:
    """The 4x4 pose a ``fraction`` of the way from ``T0`` to ``T1`` (0 gives ``T0``, 1 gives ``T1``).

    Translation interpolated linearly, rotation along the geodesic (slerp):
    ``R0 @ exp(fraction * log(R0.T @ R1))``. Fractions outside [0, 1] extrapolate.
    """
    T0 = np.asarray(T0, dtype=float)
    T1 = np.asarray(T1, dtype=float)
    out = np.eye(4)
    out[:3, :3] = T0[:3, :3] @ rotvec_to_matrix(float(fraction) * matrix_to_rotvec(T0[:3, :3].T @ T1[:3, :3]))
    out[:3, 3] = T0[:3, 3] + float(fraction) * (T1[:3, 3] - T0[:3, 3])
    return out


def fit_rigid_2d(p: np.ndarray, q: np.ndarray) -> tuple[float, float, float]:
    """Planar rigid transform ``(x, y, yaw)`` that best maps points ``q`` onto ``p`` (least squares).

    Finds ``R(yaw), t`` minimising ``sum |p_i - (R q_i + t)|^2`` over (n, 2)
    arrays of corresponding points (n >= 2, not all coincident), in closed form
    (2D Kabsch: the angle of the cross-covariance). If ``q`` are points in frame
    b and ``p`` the same points in frame a, the result is the planar pose ``T_a_b``.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != q.shape:
        raise ValueError(f"p and q must both be (n, 2), got {p.shape} and {q.shape}")
    if p.shape[0] < 2:
        raise ValueError(f"fit_rigid_2d needs at least 2 point pairs, got {p.shape[0]}")
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    dp, dq = p - pc, q - qc
    s_cos = float(np.sum(dq[:, 0] * dp[:, 0] + dq[:, 1] * dp[:, 1]))
    s_sin = float(np.sum(dq[:, 0] * dp[:, 1] - dq[:, 1] * dp[:, 0]))
    yaw = math.atan2(s_sin, s_cos)
    c, s = math.cos(yaw), math.sin(yaw)
    return float(pc[0] - (c * qc[0] - s * qc[1])), float(pc[1] - (s * qc[0] + c * qc[1])), yaw


# Fixed mount rotations (columns are the mounted frame's axes in the body frame).
#: Downward camera: optical axis -z_B, image x = -y_B (right when facing
#: forward), image y = -x_B (so the top of the image looks forward).
R_BODY_CAM_DOWN = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: Forward camera: optical axis +x_B, image x = -y_B, image y = -z_B.
R_BODY_CAM_FORWARD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: Board lying face-up on top of a robot: x_M = x_B, y_M = y_B, z_M = z_B.
R_BODY_BOARD_UP = np.eye(3)
#: Vertical board on a robot's back, printed face looking backward:
#: z_M = -x_B, y_M = z_B (up), x_M = -y_B.
R_BODY_BOARD_BACK = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: Backward camera: optical axis -x_B, image x = +y_B, image y = -z_B.
R_BODY_CAM_BACKWARD = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: Vertical board on a body's front, printed face looking forward:
#: z_M = x_B, y_M = z_B (up), x_M = y_B.
R_BODY_BOARD_FRONT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
