"""OpenCV's lens distortion model (k1, k2, p1, p2, k3) on normalised image coordinates.

Normalised coordinates are ``x = X_c / Z_c``, ``y = Y_c / Z_c`` of a point in the
camera frame C (OpenCV: x right, y down, z along the optical axis). With
``r2 = x**2 + y**2`` the distorted coordinates are::

    radial = 1 + k1*r2 + k2*r2**2 + k3*r2**3
    xd = x*radial + 2*p1*x*y + p2*(r2 + 2*x**2)
    yd = y*radial + p1*(r2 + 2*y**2) + 2*p2*x*y

which is exactly what ``cv2.projectPoints`` computes for five coefficients.

Radial distortion with negative terms folds over: beyond some radius the distorted
radius decreases again, so a point far outside the field of view would land back
inside the image. :func:`fold_radius_sq` finds that radius; the camera model treats
points beyond it as not imaged.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["N_DIST_COEFFS", "distort", "fold_radius_sq", "distorted_radius"]

#: Number of distortion coefficients of the model: (k1, k2, p1, p2, k3).
N_DIST_COEFFS = 5


def distort(
    x: np.ndarray, y: np.ndarray, dist: tuple[float, float, float, float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply the distortion to normalised coordinates.

    Args:
        x, y: arrays of normalised undistorted coordinates (same shape).
        dist: ``(k1, k2, p1, p2, k3)``.

    Returns:
        ``(xd, yd, r2)``: distorted normalised coordinates and the squared
        undistorted radius, each with the shape of ``x``.
    """
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    # Skip the terms whose coefficients are zero (the usual case): same result, fewer array ops.
    if k3 != 0.0:
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    elif k2 != 0.0:
        radial = 1.0 + r2 * (k1 + r2 * k2)
    else:
        radial = 1.0 + k1 * r2
    xd = x * radial
    yd = y * radial
    if p1 != 0.0 or p2 != 0.0:
        xy2 = 2.0 * x * y
        xd += p1 * xy2 + p2 * (r2 + 2.0 * x * x)
        yd += p1 * (r2 + 2.0 * y * y) + p2 * xy2
    return xd, yd, r2


def fold_radius_sq(dist: tuple[float, ...]) -> float:
    """Squared undistorted radius where the radial mapping stops increasing.

    The distorted radius is ``rd(r) = r * (1 + k1 r^2 + k2 r^4 + k3 r^6)``; its
    derivative ``g(s) = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3`` (``s = r^2``) is 1 at the
    centre. Returns its smallest positive root ``s``, or ``inf`` if ``rd`` never
    folds. Tangential terms are ignored (they are small for real lenses).
    """
    k1, k2, _, _, k3 = dist
    # Roots u = 1/s of the reversed polynomial u^3 g(1/u): it is monic, so tiny
    # higher-order coefficients do not spoil the roots that matter (small s).
    roots = np.roots([1.0, 3.0 * k1, 5.0 * k2, 7.0 * k3])
    largest = max((r.real for r in roots if abs(r.imag) <= 1e-7 * abs(r) and r.real > 0.0), default=0.0)
    return 1.0 / largest if largest > 1e-300 else math.inf  # (a fold beyond s = 1e300 is no fold)


def distorted_radius(r2: float, dist: tuple[float, ...]) -> float:
    """Distorted radius ``rd`` (normalised units) of an undistorted squared radius ``r2``."""
    k1, k2, _, _, k3 = dist
    return math.sqrt(r2) * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
