"""First-order uncertainty of poses through MOMA's chain of transforms.

Convention (the one of :class:`~moma_env.estimator.detection.Detection` and of a
ROS ``PoseWithCovariance``): the error of an estimate ``T_a_b = [R, t]`` of frame
b in frame a is the 6-vector ``e = (dt, dtheta)`` (m, rad), translation first,
with ``T_true = [exp([dtheta]x) R, t + dt]``: the rotation is perturbed on the
left, about the axes of frame a, and the translation additively in frame a. A
pose in the world frame W thus has its position covariance in the top-left 3x3
block and its heading (yaw) variance at ``[5, 5]``.

The functions return the Jacobians of the error of a composition, an inverse or
an upright projection with respect to the errors of their inputs. They are
exact to first order (checked against finite differences in the tests).

:class:`LinearError` is the error of one estimate as a linear function of the
errors of the frozen reference robots it was computed from, plus independent
fresh noise (the detections of this frame)::

    e = sum_s J[s] @ e_s + n,   n ~ N(0, Q)

which keeps the correlations a chain creates: every sample of a switch window
shares the reference's error, which averaging does not reduce, while the fresh
noise averages down.

Fresh noise need not be white in time: a part of it, of covariance ``P``
(included in ``Q``), may persist over the frames of a switch window (a
detection's ``persistent_covariance``: an error that stays while the camera and
the board stand still). The mean of ``n`` samples of one window then has the
fresh covariance ``(sum_i Q_i + (n - 1) sum_i P_i) / n^2`` (for equal samples
``P + (Q - P) / n``) instead of ``sum_i Q_i / n^2``
(:func:`window_mean_noise`); ``P = None`` is zero, and everything is computed
exactly as without it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numba
import numpy as np

from moma_env.geometry import kernel_array, matrix_to_rotvec, mount_rotation_kernel, pose_array, rotvec_to_matrix

__all__ = [
    "apply_error",
    "pose_error",
    "skew",
    "compose_jacobians",
    "compose_jacobian_first",
    "inverse_jacobian",
    "upright_projection_jacobian",
    "LinearError",
    "matrix6_array",
    "NO_MATRIX",
    "through_kernel",
    "pack_operands_kernel",
    "covariance_kernel",
    "covariance_one_kernel",
    "covariance_of_operands",
    "packed_operands",
    "compose_first_kernel",
    "compose_jacobians_kernel",
    "inverse_jacobian_kernel",
    "upright_jacobian_kernel",
    "RunningErrorMean",
    "window_mean_noise",
    "window_mean_noise_into",
]


def apply_error(T: np.ndarray, e: Sequence[float] | np.ndarray) -> np.ndarray:
    """The pose ``[exp([dtheta]x) R, t + dt]`` for the error ``e = (dt, dtheta)`` (m, rad) of ``T = [R, t]``."""
    e = np.asarray(e, dtype=float)
    out = np.array(T, dtype=float)
    out[:3, :3] = rotvec_to_matrix(e[3:]) @ out[:3, :3]
    out[:3, 3] = out[:3, 3] + e[:3]
    return out


def pose_error(T: np.ndarray, T_ref: np.ndarray) -> np.ndarray:
    """The error ``e`` with ``T = apply_error(T_ref, e)``: ``(t - t_ref, log(R R_ref^T))`` (m, rad)."""
    return np.concatenate([T[:3, 3] - T_ref[:3, 3], matrix_to_rotvec(T[:3, :3] @ T_ref[:3, :3].T)])


def skew(v: Sequence[float] | np.ndarray) -> np.ndarray:
    """The 3x3 matrix ``[v]x`` with ``[v]x @ w = v x w``."""
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))


def compose_jacobians(T_x_y: np.ndarray, T_y_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians ``(J_A, J_B)`` of the error of ``T_x_z = T_x_y @ T_y_z``.

    ``e(T_x_z) = J_A @ e(T_x_y) + J_B @ e(T_y_z)``, where ``e(T_x_y)`` is in
    frame x and ``e(T_y_z)`` in frame y (6x6 each)::

        J_A = [[I, -[R_x_y t_y_z]x], [0, I]]      J_B = [[R_x_y, 0], [0, R_x_y]]
    """
    return compose_jacobians_kernel(pose_array(T_x_y, "T_x_y"), pose_array(T_y_z, "T_y_z"))


def compose_jacobian_first(T_x_y: np.ndarray, T_y_z: np.ndarray) -> np.ndarray:
    """``J_A`` of :func:`compose_jacobians` alone (6x6), when the second factor is exact (a mount)."""
    return compose_first_kernel(pose_array(T_x_y, "T_x_y"), pose_array(T_y_z, "T_y_z"))


def inverse_jacobian(T_x_y: np.ndarray) -> np.ndarray:
    """Jacobian of the error of ``T_y_x = inv(T_x_y)`` (frame y) with respect to that of ``T_x_y`` (frame x)::

        [[-R^T, [t_y_x]x R^T], [0, -R^T]]    with R = R_x_y, t_y_x = -R^T t_x_y
    """
    return inverse_jacobian_kernel(pose_array(T_x_y, "T_x_y"))


def upright_projection_jacobian(T_w_x: np.ndarray, T_b_x: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`moma_env.geometry.upright_body_from_mount`'s error.

    The projection keeps the yaw of ``R_w_x @ R_b_x^T`` and places the body so
    that the mount lands on the measured x, y; height, roll and pitch are fixed,
    so rows 2, 3 and 4 of the Jacobian are zero. Input: the error of ``T_w_x``
    (world frame); output: the error of the upright ``T_w_b`` (world frame).
    """
    return upright_jacobian_kernel(pose_array(T_w_x, "T_w_x"), pose_array(T_b_x, "T_b_x"))


# The compiled forms of the Jacobians above, on float64 4x4 arrays: the arithmetic of
# numpy's products on C-ordered arrays (BLAS through np.dot, each operand in the memory
# order numpy gives it) and the C library's atan2, bit for bit (docs/estimator.md).


@numba.njit(cache=True)
def compose_first_kernel(T_x_y: np.ndarray, T_y_z: np.ndarray) -> np.ndarray:
    """:func:`compose_jacobian_first`, compiled."""
    v = np.dot(np.ascontiguousarray(T_x_y[:3, :3]), np.ascontiguousarray(T_y_z[:3, 3]))
    x, y, z = v[0], v[1], v[2]
    J = np.zeros((6, 6))
    for i in range(6):
        J[i, i] = 1.0
    # -[v]x entry by entry (its diagonal is -0.0, as negating skew(v) gives).
    J[0, 3] = -0.0
    J[0, 4] = z
    J[0, 5] = -y
    J[1, 3] = -z
    J[1, 4] = -0.0
    J[1, 5] = x
    J[2, 3] = y
    J[2, 4] = -x
    J[2, 5] = -0.0
    return J


@numba.njit(cache=True)
def compose_jacobians_kernel(T_x_y: np.ndarray, T_y_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`compose_jacobians`, compiled."""
    J_B = np.zeros((6, 6))
    J_B[:3, :3] = T_x_y[:3, :3]
    J_B[3:, 3:] = T_x_y[:3, :3]
    return compose_first_kernel(T_x_y, T_y_z), J_B


@numba.njit(cache=True)
def inverse_jacobian_kernel(T_x_y: np.ndarray) -> np.ndarray:
    """:func:`inverse_jacobian`, compiled."""
    Rt = np.asfortranarray(T_x_y[:3, :3].T)
    minus_Rt = -Rt  # column-major, as numpy's negation of the transposed view
    v = np.dot(minus_Rt, np.ascontiguousarray(T_x_y[:3, 3]))
    x, y, z = v[0], v[1], v[2]
    S = np.zeros((3, 3))  # skew(v), its zeros +0.0
    S[0, 1] = -z
    S[0, 2] = y
    S[1, 0] = z
    S[1, 2] = -x
    S[2, 0] = -y
    S[2, 1] = x
    J = np.zeros((6, 6))
    J[:3, :3] = minus_Rt
    J[:3, 3:] = np.dot(S, Rt)
    J[3:, 3:] = minus_Rt
    return J


@numba.njit(cache=True)
def upright_jacobian_kernel(T_w_x: np.ndarray, T_b_x: np.ndarray) -> np.ndarray:
    """:func:`upright_projection_jacobian`, compiled."""
    R0 = mount_rotation_kernel(T_w_x, T_b_x)
    cx, cy, cz = R0[0, 0], R0[1, 0], R0[2, 0]
    h2 = cx * cx + cy * cy
    yaw = math.atan2(cy, cx)
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty = T_b_x[0, 3], T_b_x[1, 3]
    # d yaw / d dtheta for R = exp([dtheta]x) R0, yaw = atan2(R[1, 0], R[0, 0]).
    d0, d1, d2 = -cz * cx / h2, -cz * cy / h2, 1.0
    a = s * tx + c * ty
    b = -(c * tx - s * ty)
    J = np.zeros((6, 6))
    J[0, 0] = 1.0
    J[1, 1] = 1.0
    J[0, 3], J[0, 4], J[0, 5] = a * d0, a * d1, a * d2
    J[1, 3], J[1, 4], J[1, 5] = b * d0, b * d1, b * d2
    J[5, 3], J[5, 4], J[5, 5] = d0, d1, d2
    return J


def window_mean_noise(Q_sum: np.ndarray, P_sum: np.ndarray | None, n: int) -> np.ndarray:
    """Fresh-noise covariance of the mean of ``n`` samples of one switch window (6x6).

    ``Q_sum`` is the sum of the samples' fresh covariances ``Q_i``, ``P_sum`` the
    sum of their persistent parts ``P_i`` (None: none). The persistent parts of
    two samples of a window are taken as fully correlated (the same draw, its
    covariance the mean of theirs), the rest as independent::

        Cov(mean) = (sum_i Q_i + (n - 1) sum_i P_i) / n^2

    With ``P_sum`` None this is ``Q_sum / n^2``, bit for bit. The arithmetic is
    :func:`window_mean_noise_into`'s (what a switch window's compiled mean computes).
    """
    Q_sum = np.asarray(Q_sum, dtype=float)
    out = np.empty(Q_sum.shape)
    has_P = P_sum is not None
    window_mean_noise_into(Q_sum, np.asarray(P_sum, dtype=float) if has_P else Q_sum, has_P, n, out)
    return out


@numba.njit(cache=True, error_model="numpy")  # n = 0 divides as numpy does, to NaN
def window_mean_noise_into(Q_sum: np.ndarray, P_sum: np.ndarray, has_P: bool, n: int, out: np.ndarray) -> None:
    """:func:`window_mean_noise` of 2-D arrays into ``out``, compiled, element by element:
    ``(Q + (n - 1) P) / n^2``, or ``Q / n^2`` when not ``has_P`` (``P_sum`` then unread),
    the arithmetic numpy applies to the whole arrays."""
    for r in range(Q_sum.shape[0]):
        for c in range(Q_sum.shape[1]):
            if has_P:
                out[r, c] = (Q_sum[r, c] + (n - 1) * P_sum[r, c]) / (n * n)
            else:
                out[r, c] = Q_sum[r, c] / (n * n)


#: Stand-ins for an absent matrix in the compiled calls (never read: a flag says so).
NO_MATRIX = np.zeros((6, 6))
NO_MATRIX.flags.writeable = False
# No Jacobian: empty, so writable like the stacks of Jacobians covariance_kernel is otherwise
# given (a read-only array is another type to numba, and another compilation).
_NO_JACOBIANS = np.zeros((0, 6, 6))


def matrix6_array(M: object, name: str = "matrix") -> np.ndarray:
    """``M`` as a C-ordered float64 6x6 array (itself when it is one), for the compiled calls."""
    return kernel_array(M, (6, 6), name)


def noise_operands(covariance: np.ndarray | None, persistent: np.ndarray | None) -> tuple[np.ndarray, bool, np.ndarray, bool]:
    """A measurement's noise as the compiled calls take it: ``(covariance, given, persistent, given)``,
    C-ordered float64 6x6 arrays, zero stand-ins where absent (a persistent part only with a covariance)."""
    if covariance is None:
        return NO_MATRIX, False, NO_MATRIX, False
    if persistent is None:
        return matrix6_array(covariance), True, NO_MATRIX, False
    return matrix6_array(covariance), True, matrix6_array(persistent), True


@numba.njit(cache=True)
def through_kernel(Js, Q, P, has_P, transform, A, B, covariance, has_covariance, persistent, has_persistent):
    """:meth:`LinearError.through`, compiled: ``(A @ J[s] for each s, Q', P', whether P' exists)``
    (``A`` the identity unless ``transform``) with numpy's products (``A @ X @ A.T`` as
    ``(A @ X) @ A.T``), bit for bit."""
    if transform:
        out = np.empty_like(Js)
        for k in range(Js.shape[0]):
            out[k] = np.dot(A, Js[k])
        Q_out = np.dot(np.dot(A, Q), A.T)
        P_out = np.dot(np.dot(A, P), A.T) if has_P else np.zeros((6, 6))
    else:
        out, Q_out, P_out = Js.copy(), Q.copy(), P.copy()
    if has_covariance:
        if has_persistent:
            added = np.dot(np.dot(B, persistent), B.T)
            P_out = P_out + added if has_P else added
            has_P = True
        Q_out = Q_out + np.dot(np.dot(B, covariance), B.T)
    return out, Q_out, P_out, has_P


@numba.njit(cache=True)
def pack_operands_kernel(Js, Q, P):
    """An error's operands (:meth:`LinearError.operands`) as one ``(k + 2, 6, 6)`` array: the
    ``k`` Jacobians, then ``Q``, then ``P`` (:meth:`LinearError.of_packed` reads it). A compiled
    call returning it boxes one array instead of three (each returned array costs ~0.7 us)."""
    k = Js.shape[0]
    out = np.empty((k + 2, 6, 6))
    out[:k] = Js
    out[k] = Q
    out[k + 1] = P
    return out


@numba.njit(cache=True)
def covariance_kernel(Js, blocks, Q):
    """:meth:`LinearError.covariance`, compiled: ``Q + sum over s, then r, of J[s] @ P[(s, r)] @ J[r].T``
    (``blocks[s * K + r]`` is ``P[(s, r)]``), added in that order, then symmetrised as
    ``(S + S.T) * 0.5``; numpy's products, bit for bit."""
    k = Js.shape[0]
    S = Q.copy()
    for s in range(k):
        for r in range(k):
            S = S + np.dot(np.dot(Js[s], blocks[s * k + r]), Js[r].T)
    return (S + S.T) * 0.5


@numba.njit(cache=True)
def covariance_one_kernel(J, block, Q):
    """:func:`covariance_kernel` of an error with one reference, taking its 6x6 Jacobian ``J``
    and ``block = P[(s, s)]`` as they are (copied C-ordered here, as ``np.ascontiguousarray``
    gives them to :func:`covariance_kernel`): ``Q + J @ block @ J.T``, symmetrised, the same bits.
    One call without the Python wrapping of stacked operands (the usual case of the update)."""
    Jc = np.ascontiguousarray(J)
    S = Q.copy()
    S = S + np.dot(np.dot(Jc, np.ascontiguousarray(block)), Jc.T)
    return (S + S.T) * 0.5


def packed_operands(keys: list, packed: np.ndarray, has_P: bool) -> tuple[list, np.ndarray, np.ndarray, np.ndarray, bool]:
    """:meth:`LinearError.operands` of ``LinearError.of_packed(keys, packed, has_P)``, without
    making the error: ``(keys, packed[:k], packed[k], packed[k + 1] or a zero stand-in, has_P)``,
    views of ``packed`` (the layout of :func:`pack_operands_kernel`)."""
    k = len(keys)
    return keys, packed[:k], packed[k], packed[k + 1] if has_P else NO_MATRIX, has_P


def covariance_of_operands(keys: Sequence, stack: np.ndarray, Q: np.ndarray, P: Mapping[tuple, np.ndarray]) -> np.ndarray:
    """:meth:`LinearError.covariance` of the error of these operands (:meth:`LinearError.operands`:
    its reference ``keys``, their Jacobians stacked, its fresh noise ``Q``) under the joint
    covariance ``P[(s, r)]``: the same compiled calls on the same values, the same bits."""
    if len(keys) == 1:
        s = keys[0]
        return covariance_one_kernel(stack[0], P[(s, s)], Q)
    if not keys:
        return covariance_kernel(_NO_JACOBIANS, _NO_JACOBIANS, Q)
    return covariance_kernel(stack, np.array([P[(s, r)] for s in keys for r in keys]), Q)


class LinearError:
    """The error of one estimate: ``e = sum_s J[s] @ e_s + n``, ``n ~ N(0, Q)`` (6-vectors).

    Attributes:
        J: reference name -> 6x6 Jacobian with respect to that reference robot's
            error (world frame). Treated as read-only.
        Q: 6x6 covariance of the fresh noise, independent of every reference.
        P: 6x6 part of ``Q`` that persists over the samples of a switch window
            (see the module docstring), or None (none: white noise).
    """

    __slots__ = ("J", "Q", "P")

    def __init__(
        self, J: Mapping[str, np.ndarray] | None = None, Q: np.ndarray | None = None, P: np.ndarray | None = None
    ):
        self.J = dict(J) if J else {}
        self.Q = np.zeros((6, 6)) if Q is None else Q
        self.P = P

    @classmethod
    def of_reference(cls, name: str) -> LinearError:
        """The error of a frozen reference robot's own pose."""
        return cls({name: np.eye(6)})

    @classmethod
    def _of(cls, J: dict[str, np.ndarray], Q: np.ndarray, P: np.ndarray | None = None) -> LinearError:
        """A new error owning the new dict ``J`` (not copied), ``Q`` and ``P``."""
        error = cls.__new__(cls)
        error.J = J
        error.Q = Q
        error.P = P
        return error

    @classmethod
    def of_jacobian(cls, reference: int | str, J: np.ndarray, Q: np.ndarray, P: np.ndarray | None = None) -> LinearError:
        """The error ``J @ e_reference + n``, ``n`` of covariance ``Q`` (persistent part ``P``),
        owning the arrays given (not copied)."""
        return cls._of({reference: J}, Q, P)

    def transformed(self, A: np.ndarray) -> LinearError:
        """The error ``A @ e``."""
        return self.through(A, None, None)

    def through(
        self, A: np.ndarray | None, B: np.ndarray | None, covariance: np.ndarray | None, persistent: np.ndarray | None = None
    ) -> LinearError:
        """``self.transformed(A).plus_noise(B, covariance, persistent)`` in one compiled call, the
        same bits: the error ``A @ e + B @ n`` of an estimate computed from this one and a fresh
        measurement ``n`` (``A`` None: no transform; ``B`` is ignored when ``covariance`` is None)."""
        keys, stack, Q, P, has_P = self.operands()
        with_noise = covariance is not None
        Js, Q, P_out, has_P = through_kernel(
            stack, Q, P, has_P, A is not None, NO_MATRIX if A is None else matrix6_array(A),
            matrix6_array(B) if with_noise else NO_MATRIX, *noise_operands(covariance, persistent),
        )
        return LinearError.of_operands(keys, Js, Q, P_out, has_P)

    def operands(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray, bool]:
        """What the compiled calls take of this error: ``(keys, J stacked (k, 6, 6) in the keys'
        order, Q, P or a zero stand-in, whether P exists)``; :meth:`of_operands` inverts it."""
        J = self.J
        keys = list(J)
        if len(keys) == 1:  # the usual case: a view, no copy
            stack = np.ascontiguousarray(J[keys[0]])[None]
        else:
            stack = np.array(list(J.values())) if keys else _NO_JACOBIANS
        P = self.P
        return keys, stack, self.Q, NO_MATRIX if P is None else P, P is not None

    @classmethod
    def of_operands(cls, keys: Sequence, Js: np.ndarray, Q: np.ndarray, P: np.ndarray, has_P: bool) -> LinearError:
        """A new error from a compiled call's results, in the layout of :meth:`operands` (owning them)."""
        return cls._of(dict(zip(keys, Js)), Q, P if has_P else None)

    @classmethod
    def of_packed(cls, keys: Sequence, packed: np.ndarray, has_P: bool) -> LinearError:
        """A new error from a compiled call's results packed by :func:`pack_operands_kernel`
        (its ``J``, ``Q`` and ``P`` are views of ``packed``, which it owns)."""
        k = len(keys)
        error = cls.__new__(cls)
        # One key (the usual case): the dict built directly, half the cost of dict(zip(...)).
        error.J = {keys[0]: packed[0]} if k == 1 else dict(zip(keys, packed))
        error.Q = packed[k]
        error.P = packed[k + 1] if has_P else None
        return error

    def plus_noise(
        self, A: np.ndarray, covariance: np.ndarray | None, persistent: np.ndarray | None = None
    ) -> LinearError:
        """A new error: this one plus ``A @ n`` for fresh noise ``n`` of ``covariance`` (None: no noise),
        of which the part of covariance ``persistent`` (None: none) persists over a switch window."""
        return self.through(None, A, covariance, persistent)

    @staticmethod
    def mean(errors: Sequence[LinearError]) -> LinearError:
        """The error of the mean of estimates with these errors, their fresh noises independent
        (persistent parts included: independent of each other, e.g. different boards of one frame);
        the one error itself when there is one."""
        if len(errors) == 1:
            return errors[0]
        return RunningErrorMean().mean(errors)

    def covariance(self, P: Mapping[tuple[str, str], np.ndarray]) -> np.ndarray:
        """6x6 covariance, given the joint covariance ``P[(s, r)]`` of the references' errors."""
        J = self.J
        if len(J) == 1:  # the usual case: one reference, no stacked operands
            ((s, Js),) = J.items()
            return covariance_one_kernel(Js, P[(s, s)], self.Q)
        return covariance_of_operands(list(J), np.array(list(J.values())) if J else _NO_JACOBIANS, self.Q, P)

    def cross(self, P: Mapping[tuple[str, str], np.ndarray], other: str) -> np.ndarray:
        """6x6 covariance ``E[e e_other^T]`` with reference ``other``'s error (fresh noise is independent of it)."""
        C = np.zeros((6, 6))
        for s, Js in self.J.items():
            C += Js @ P[(s, other)]
        return C

    def references(self) -> Iterable[str]:
        """The references this error depends on."""
        return self.J.keys()


class RunningErrorMean:
    """:meth:`LinearError.mean` of a list of errors that mostly grows at its end.

    While the list only gains errors at the end, the sums of their Jacobians and noise
    covariances are carried over and only the new errors are added, in the same order
    as :meth:`LinearError.mean` adds them, so the result is the same to the bit. Any
    other change starts the sums afresh. Errors are recognised by identity and treated
    as read-only, as everywhere. (A switch window's mean error, whose persistent parts
    are one draw, is :class:`~moma_env.estimator.window.SettlingWindow`'s.)
    """

    __slots__ = ("_errors", "_J", "_Q", "_P", "_mean")

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        """Forget the sums."""
        self._errors: list[LinearError] = []
        self._J: dict[str, np.ndarray] = {}
        self._Q = np.zeros((6, 6))
        self._P: np.ndarray | None = None
        self._mean: LinearError | None = None

    def mean(self, errors: Sequence[LinearError]) -> LinearError:
        """``LinearError.mean(errors)`` (the same object for the same list, unchanged)."""
        summed = self._errors
        m = len(summed)
        n = len(errors)
        # Whether the summed errors are not the first of ``errors``, in one list comparison:
        # by identity here (a LinearError compares equal only to itself).
        fresh = m > n or (m > 0 and summed != list(errors[:m]))
        if fresh:
            self.clear()
            summed = self._errors
            m = 0
        elif m == n and self._mean is not None:
            return self._mean
        J = self._J
        Q = self._Q
        for k in range(m, n):
            e = errors[k]
            for s, Js in e.J.items():
                if s in J:
                    J[s] += Js
                else:
                    J[s] = Js.copy()
            Q += e.Q
            if e.P is not None:
                if self._P is None:
                    self._P = e.P.copy()
                else:
                    self._P += e.P
            summed.append(e)
        P = self._P
        if n == 1:
            mean = errors[0]
        elif P is None:
            mean = LinearError._of({s: Js / n for s, Js in J.items()}, Q / (n * n))
        else:
            mean = LinearError._of({s: Js / n for s, Js in J.items()}, Q / (n * n), P / (n * n))
        self._mean = mean
        return mean
