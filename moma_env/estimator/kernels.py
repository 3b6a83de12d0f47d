"""Compiled steps of the MOMA update (numba), bit for bit the numpy arithmetic they replace.

Each takes float64 arrays and repeats numpy's products on C-ordered arrays (BLAS
through ``np.dot``, every operand in the memory order numpy gives BLAS) and the C
library's functions (docs/estimator.md, "Its arithmetic"), so moving a step here
changes no fingerprint. They are built from the helpers' kernels of
:mod:`moma_env.geometry` and :mod:`moma_env.estimator.uncertainty`.
"""

from __future__ import annotations

import numba
import numpy as np

from moma_env.geometry import invert_kernel, upright_body_kernel
from moma_env.estimator.uncertainty import (
    compose_first_kernel,
    compose_jacobians_kernel,
    inverse_jacobian_kernel,
    pack_operands_kernel,
    through_kernel,
    upright_jacobian_kernel,
)

__all__ = [
    "camera_from_reference_board",
    "body_from_mounted_frame",
    "body_from_board_seen",
    "sample_from_board_seen",
    "packed_sample_from_board_seen",
    "packed_sample_from_mounted_frame",
    "packed_camera_from_reference_board",
]


@numba.njit(cache=True)
def camera_from_reference_board(T_w_m, board_J, T_c_m, covariance, has_covariance, persistent, has_persistent):
    """A camera located from a board of a frozen reference robot.

    Args (float64; 4x4 poses, 6x6 matrices): ``T_w_m`` the board's frozen pose,
    ``board_J`` its Jacobian with respect to the reference's error, ``T_c_m`` the
    detection, ``covariance`` / ``persistent`` its noise (read only when the flags say so).

    Returns ``(T_w_c, J, Q, P)``: the camera pose ``T_w_m @ inv(T_c_m)``, the Jacobian
    of its error with respect to the reference's, the fresh noise (zero without a
    covariance; ``+ 0.0``: no ``-0.0`` entries) and its persistent part (zero without one).
    """
    T_m_c = invert_kernel(T_c_m)
    J_ref, J_meas = compose_jacobians_kernel(T_w_m, T_m_c)
    J = np.dot(J_ref, board_J)
    Q = np.zeros((6, 6))
    P = np.zeros((6, 6))
    if has_covariance:
        A = np.dot(J_meas, inverse_jacobian_kernel(T_c_m))
        Q = np.dot(np.dot(A, covariance), A.T) + 0.0
        if has_persistent:
            P = np.dot(np.dot(A, persistent), A.T)
    return np.dot(T_w_m, T_m_c), J, Q, P


@numba.njit(cache=True)
def body_from_mounted_frame(T_w_x, T_b_x, T_x_b, planar, plane_z):
    """A robot's body pose from the measured pose ``T_w_x`` of a frame x mounted at ``T_b_x``
    (``T_x_b`` its inverse): upright on the plane at height ``plane_z`` when ``planar``
    (:func:`~moma_env.geometry.upright_body_from_mount`), else ``T_w_x @ T_x_b``; and the
    Jacobian of its error with respect to ``T_w_x``'s. Returns ``(T_w_b, A)``."""
    if planar:
        return upright_body_kernel(T_w_x, T_b_x, plane_z), upright_jacobian_kernel(T_w_x, T_b_x)
    return np.dot(T_w_x, T_x_b), compose_first_kernel(T_w_x, T_x_b)


@numba.njit(cache=True)
def packed_sample_from_mounted_frame(T_w_x, T_b_x, T_x_b, planar, plane_z, Js, Q, P, has_P):
    """:func:`body_from_mounted_frame`, then the sample's error from the measured frame's
    (``Js``, ``Q``, ``P``, ``has_P``: :meth:`LinearError.operands
    <moma_env.estimator.uncertainty.LinearError.operands>`) as :meth:`LinearError.transformed
    <moma_env.estimator.uncertainty.LinearError.transformed>` gives it: one call, the same bits.
    Returns ``(T_w_b, packed error, has_P')``, the error packed by
    :func:`~moma_env.estimator.uncertainty.pack_operands_kernel`."""
    sample, A = body_from_mounted_frame(T_w_x, T_b_x, T_x_b, planar, plane_z)
    # No fresh noise: the noise operands are never read (A stands in for them).
    Js_out, Q_out, P_out, has_P_out = through_kernel(Js, Q, P, has_P, True, A, A, A, False, A, False)
    return sample, pack_operands_kernel(Js_out, Q_out, P_out), has_P_out


@numba.njit(cache=True)
def body_from_board_seen(T_w_c, T_c_m, T_b_m, T_m_b, planar, plane_z):
    """A robot's body pose from its board (mounted at ``T_b_m``, ``T_m_b`` its inverse) seen
    as ``T_c_m`` by a camera at ``T_w_c``. Returns ``(T_w_b, A_cam, A_meas)``: the pose and the
    Jacobians of its error with respect to the camera's and the detection's."""
    T_w_m = np.dot(T_w_c, T_c_m)
    J_cam, J_meas = compose_jacobians_kernel(T_w_c, T_c_m)
    sample, A = body_from_mounted_frame(T_w_m, T_b_m, T_m_b, planar, plane_z)
    return sample, np.dot(A, J_cam), np.dot(A, J_meas)


@numba.njit(cache=True)
def sample_from_board_seen(
    T_w_c, T_c_m, T_b_m, T_m_b, planar, plane_z, Js, Q, P, has_P, covariance, has_covariance, persistent, has_persistent
):
    """:func:`body_from_board_seen`, then the sample's error from the camera's (``Js``, ``Q``,
    ``P``, ``has_P``: :meth:`LinearError.operands <moma_env.estimator.uncertainty.LinearError.operands>`)
    and the detection's noise, as :meth:`LinearError.through
    <moma_env.estimator.uncertainty.LinearError.through>` gives it: one call, the same bits.
    Returns ``(T_w_b, Js', Q', P', has_P')``."""
    sample, A_cam, A_meas = body_from_board_seen(T_w_c, T_c_m, T_b_m, T_m_b, planar, plane_z)
    Js_out, Q_out, P_out, has_P_out = through_kernel(
        Js, Q, P, has_P, True, A_cam, A_meas, covariance, has_covariance, persistent, has_persistent
    )
    return sample, Js_out, Q_out, P_out, has_P_out


@numba.njit(cache=True)
def packed_sample_from_board_seen(
    T_w_c, T_c_m, T_b_m, T_m_b, planar, plane_z, Js, Q, P, has_P, covariance, has_covariance, persistent, has_persistent
):
    """:func:`sample_from_board_seen` returning ``(T_w_b, packed error, has_P')``, the error packed
    by :func:`~moma_env.estimator.uncertainty.pack_operands_kernel` (two arrays to box, not four)."""
    sample, Js_out, Q_out, P_out, has_P_out = sample_from_board_seen(
        T_w_c, T_c_m, T_b_m, T_m_b, planar, plane_z, Js, Q, P, has_P, covariance, has_covariance, persistent, has_persistent
    )
    return sample, pack_operands_kernel(Js_out, Q_out, P_out), has_P_out


@numba.njit(cache=True)
def packed_camera_from_reference_board(T_w_m, board_J, T_c_m, covariance, has_covariance, persistent, has_persistent):
    """:func:`camera_from_reference_board` returning ``(T_w_c, packed error)``: its ``J``, ``Q``
    and ``P`` packed by :func:`~moma_env.estimator.uncertainty.pack_operands_kernel`."""
    T_w_c, J, Q, P = camera_from_reference_board(T_w_m, board_J, T_c_m, covariance, has_covariance, persistent, has_persistent)
    return T_w_c, pack_operands_kernel(J.reshape((1, 6, 6)), Q, P)
