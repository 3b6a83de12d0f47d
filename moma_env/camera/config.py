"""Camera configuration: intrinsics, lens distortion, pixel noise and visibility limits.

Defaults are a generic PAL observer camera: 720x576 px, square pixels, the
principal point at the image centre, a mild barrel distortion and about half a
pixel of corner noise. The authors' calibrated camera (non-square pixels, an
off-centre principal point, k1 = -0.42) is
``training.experiments.presets.PAPER_CAMERA``; every part of the camera model
takes ``fx != fy``, any principal point inside the image and any distortion
whose radial mapping is one-to-one over the image.

Pixel convention (OpenCV): pixel centres sit at integer coordinates ``(u, v)``,
``u`` to the right, ``v`` down, so the sensor spans ``[-0.5, width - 0.5] x
[-0.5, height - 0.5]`` and its centre is ``((width - 1) / 2, (height - 1) / 2)``.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar

from moma_env.camera.distortion import N_DIST_COEFFS, distorted_radius, fold_radius_sq
from moma_env.config import (
    ConfigError,
    check_choice,
    check_finite,
    check_non_negative,
    check_positive,
    check_range,
)

__all__ = ["CameraConfig", "PNP_METHODS", "POSE_DISAMBIGUATIONS", "PNP_SIGMA_SOURCES"]

#: PnP methods a camera may use: ``PLANAR_LM`` (:mod:`moma_env.camera.planar_pnp`)
#: or OpenCV's (names of ``cv2.SOLVEPNP_*`` without the prefix).
PNP_METHODS = ("PLANAR_LM", "IPPE", "ITERATIVE", "SQPNP")
#: How a camera chooses between the two poses of the planar ambiguity (see ``CameraConfig``).
POSE_DISAMBIGUATIONS = ("upright", "min_cost")
#: Where the corner noise of a detection's covariance comes from (see ``CameraConfig``).
PNP_SIGMA_SOURCES = ("auto", "noise_px", "residuals")


def _check_positive_int(field: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ConfigError(field, f"must be an integer, got {value!r}")
    if value <= 0:
        raise ConfigError(field, f"must be > 0, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class CameraConfig:
    """Intrinsics, distortion, noise and visibility limits of one camera.

    Attributes:
        width, height: image size (px).
        fx, fy: focal lengths (px). ``fy=None`` means square pixels (``fy = fx``).
        cx, cy: principal point (px); ``None`` means the image centre,
            ``((width - 1) / 2, (height - 1) / 2)``.
        dist: OpenCV distortion ``(k1, k2, p1, p2, k3)``; fewer values mean the
            missing trailing ones are zero. Stored as five floats. The radial
            mapping must be one-to-one over the whole image (no fold-over).
        noise_px: standard deviation of the Gaussian noise added to each corner
            coordinate (px).
        margin_px: a marker corner must lie this far inside the sensor border (px).
        min_marker_px: shortest imaged side of a marker for it to be detected (px).
        max_incidence_deg: largest angle between the board normal z_M and the
            direction from the marker to the camera (deg), in (0, 90].
        min_range_m: every corner must be at least this far in front of the camera
            (depth z_C, m).
        max_range_m: largest distance from the camera centre to a marker centre (m).
        pnp_method: ``"PLANAR_LM"`` (default: homography, then Levenberg-Marquardt
            on the reprojection error from both poses of the planar ambiguity,
            compiled; see :mod:`moma_env.camera.planar_pnp`: the maximum-likelihood
            pose, about 4x cheaper than SQPNP and at least as accurate),
            ``"SQPNP"`` (OpenCV's globally optimal least-squares solver; on
            face-on boards its rotation error is less than half of IPPE's, which
            decides whether the caterpillars reach their goals: the default
            caterpillar scenario succeeds in 10 of 10 seeds with SQPNP, 7 of 10
            with IPPE), ``"ITERATIVE"`` (IPPE, then OpenCV's Levenberg-Marquardt)
            or ``"IPPE"`` (OpenCV's closed form for planar targets). All are exact
            without noise.
        pose_disambiguation: how the camera chooses between the two poses of the
            planar ambiguity (the "flip": see ``docs/pnp.md``). ``"upright"``
            (default): both are refined with the upright prior in the cost (the
            maximum a posteriori pose) and the more probable one is kept: the board's up direction as its mount declares
            it (``BoardView.up_m``) against world up in C from the camera's attitude,
            weighed against the reprojection cost (see
            :func:`moma_env.camera.kernels.solve_boards`); boards without
            ``up_m`` get the lower cost. With an OpenCV ``pnp_method`` the OpenCV
            pose and its mirror image are both refined by the same
            Levenberg-Marquardt first. ``"min_cost"``: the lower reprojection
            cost (the OpenCV methods: OpenCV's own pose), the rule before the prior.
        upright_prior_deg: standard deviation (deg, > 0) of the angle between a
            board's up direction as its mount declares it and as it really is
            (robot tilt on the floor, mount tolerance); the camera's
            ``attitude_noise_deg`` is added to it in quadrature.
        attitude_noise_deg: standard deviation (deg, >= 0) of the error of the
            camera's knowledge of gravity (IMU / attitude estimate, or the mount
            of a robot camera), simulated as a random rotation of world up in C,
            drawn once per ``measure`` call after the corner noise. 0 (default)
            draws nothing.
        pnp_sigma_source: the corner noise std ``sigma`` (px) of each
            detection's covariance ``sigma^2 inv(J^T J)``: ``"noise_px"`` (the
            configured noise), ``"residuals"`` (estimated per board from the
            chosen pose's residuals, ``sqrt(cost / (2 n - 6))`` for n corners, at
            least ``pnp_sigma_floor_px``) or ``"auto"`` (default: ``noise_px`` for
            the geometric backend, ``residuals`` for the rendered one, whose
            noise is in the image).
        pnp_sigma_floor_px: smallest estimated corner noise std (px, >= 0): a
            board whose corners happen to fit almost exactly is not reported as
            certain.
        pnp_warm_start: warm-started PnP (``pnp_method="PLANAR_LM"`` of the
            geometric backend; the OpenCV methods and the rendered backend
            always solve from scratch). The camera remembers the pose ``T_c_m``
            of every board it detected in its previous frame; in the next frame
            (a later ``time``) that board's solve starts from it: a few
            Levenberg-Marquardt iterations on the same cost the full solve
            minimises, accepted only if the mirror pose of the planar ambiguity
            is clearly worse (see
            :func:`moma_env.camera.planar_pnp.refine_warm_start`) and the RMS
            reprojection error is at most ``pnp_warm_max_rms_px``; otherwise
            (and for boards not detected in the previous frame) the full solve.
            ``GeometricCamera.reset()`` forgets the poses (a new episode).
        pnp_warm_max_rms_px: largest RMS reprojection error (px, finite, >=
            ``noise_px`` and > 0) of an accepted warm start; None (default):
            ``3 * max(noise_px, pnp_sigma_floor_px)`` (:attr:`warm_max_rms_px`),
            about twice the RMS error of a correct pose (``~1.3 noise_px`` for
            a 16-corner board), so it rejects poses that fell into a wrong
            minimum after a jump and practically never a correct one.
        board_shift_px: std (px, >= 0) of an error shared by every corner of
            a board (a shift of its image in u and in v), added to each
            detection's covariance as the lateral translation it gives at the
            board's depth (:mod:`moma_env.camera.board_shift`). None
            (default): the backend's: none for the geometric backend (a
            non-zero value is an error there: it draws no such shift), the
            measured ``RENDERED_SHIFT_PX`` for the rendered one.
        board_shift_persistence: fraction (in [0, 1]) of the shift's variance
            that persists while the camera and the board stand still (each
            detection's ``persistent_covariance``). None (default): the
            backend's (the measured ``RENDERED_SHIFT_PERSISTENCE`` for the
            rendered one).
    """

    #: The settings of the pose solver and of the noise model, which random layouts never
    #: draw (``moma_env.scenarios.sampling.random_camera`` draws ``fx``, ``noise_px`` and
    #: ``dist``) and keep from an env's ``camera`` override. The image, the principal point
    #: and the visibility limits are not among them: they decide which boards a layout's
    #: cameras see at the start, which the draws check.
    SETTING_FIELDS: ClassVar[tuple[str, ...]] = (
        "pnp_method",
        "pose_disambiguation",
        "upright_prior_deg",
        "attitude_noise_deg",
        "pnp_sigma_source",
        "pnp_sigma_floor_px",
        "pnp_warm_start",
        "pnp_warm_max_rms_px",
        "board_shift_px",
        "board_shift_persistence",
    )

    width: int = 720
    height: int = 576
    fx: float = 420.0
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    dist: tuple[float, ...] = (-0.05, 0.01, 0.0, 0.0, 0.0)
    noise_px: float = 0.5
    margin_px: float = 5.0
    min_marker_px: float = 12.0
    max_incidence_deg: float = 70.0
    min_range_m: float = 0.1
    max_range_m: float = 8.0
    pnp_method: str = "PLANAR_LM"
    pose_disambiguation: str = "upright"
    upright_prior_deg: float = 3.0
    attitude_noise_deg: float = 0.0
    pnp_sigma_source: str = "auto"
    pnp_sigma_floor_px: float = 0.1
    pnp_warm_start: bool = False
    pnp_warm_max_rms_px: float | None = None
    board_shift_px: float | None = None
    board_shift_persistence: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", _check_positive_int("camera.width", self.width))
        object.__setattr__(self, "height", _check_positive_int("camera.height", self.height))
        check_positive("camera.fx", self.fx)
        if self.fy is None:
            object.__setattr__(self, "fy", float(self.fx))
        check_positive("camera.fy", self.fy)
        if self.cx is None:
            object.__setattr__(self, "cx", (self.width - 1) / 2.0)
        if self.cy is None:
            object.__setattr__(self, "cy", (self.height - 1) / 2.0)
        check_range("camera.cx", self.cx, -0.5, self.width - 0.5)
        check_range("camera.cy", self.cy, -0.5, self.height - 0.5)
        for name in ("fx", "fy", "cx", "cy"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "dist", self._validated_dist())
        check_non_negative("camera.noise_px", self.noise_px)
        check_non_negative("camera.margin_px", self.margin_px)
        if 2.0 * self.margin_px >= min(self.width, self.height):
            raise ConfigError(
                "camera.margin_px", f"leaves no image area ({self.margin_px} px on a {self.width}x{self.height} image)"
            )
        check_non_negative("camera.min_marker_px", self.min_marker_px)
        check_finite("camera.max_incidence_deg", self.max_incidence_deg)
        if not 0.0 < self.max_incidence_deg <= 90.0:
            raise ConfigError("camera.max_incidence_deg", f"must be in (0, 90], got {self.max_incidence_deg!r}")
        check_positive("camera.min_range_m", self.min_range_m)
        check_positive("camera.max_range_m", self.max_range_m)
        if self.max_range_m <= self.min_range_m:
            raise ConfigError(
                "camera.max_range_m", f"must exceed min_range_m={self.min_range_m}, got {self.max_range_m!r}"
            )
        check_choice("camera.pnp_method", self.pnp_method, PNP_METHODS)
        check_choice("camera.pose_disambiguation", self.pose_disambiguation, POSE_DISAMBIGUATIONS)
        check_positive("camera.upright_prior_deg", self.upright_prior_deg)
        check_non_negative("camera.attitude_noise_deg", self.attitude_noise_deg)
        check_choice("camera.pnp_sigma_source", self.pnp_sigma_source, PNP_SIGMA_SOURCES)
        check_non_negative("camera.pnp_sigma_floor_px", self.pnp_sigma_floor_px)
        if not isinstance(self.pnp_warm_start, bool):
            raise ConfigError("camera.pnp_warm_start", f"must be True or False, got {self.pnp_warm_start!r}")
        if self.pnp_warm_max_rms_px is not None:
            check_positive("camera.pnp_warm_max_rms_px", self.pnp_warm_max_rms_px)
            if self.pnp_warm_max_rms_px < self.noise_px:
                raise ConfigError(
                    "camera.pnp_warm_max_rms_px",
                    f"must be at least noise_px={self.noise_px} (a correct pose's RMS error is about "
                    f"1.3 noise_px: nearly every warm start would be rejected), got {self.pnp_warm_max_rms_px!r}",
                )
            object.__setattr__(self, "pnp_warm_max_rms_px", float(self.pnp_warm_max_rms_px))
        if self.board_shift_px is not None:
            check_non_negative("camera.board_shift_px", self.board_shift_px)
            object.__setattr__(self, "board_shift_px", float(self.board_shift_px))
        if self.board_shift_persistence is not None:
            check_range("camera.board_shift_persistence", self.board_shift_persistence, 0.0, 1.0)
            object.__setattr__(self, "board_shift_persistence", float(self.board_shift_persistence))

    @property
    def warm_max_rms_px(self) -> float:
        """The RMS reprojection error (px) up to which a warm-started pose is accepted
        (``pnp_warm_max_rms_px``, or its default ``3 * max(noise_px, pnp_sigma_floor_px)``)."""
        if self.pnp_warm_max_rms_px is not None:
            return self.pnp_warm_max_rms_px
        return 3.0 * max(self.noise_px, self.pnp_sigma_floor_px)

    def _validated_dist(self) -> tuple[float, float, float, float, float]:
        try:
            coeffs = tuple(self.dist)
        except TypeError:
            raise ConfigError("camera.dist", f"must be a sequence of numbers, got {self.dist!r}") from None
        if len(coeffs) > N_DIST_COEFFS:
            raise ConfigError(
                "camera.dist", f"at most {N_DIST_COEFFS} coefficients (k1, k2, p1, p2, k3), got {len(coeffs)}"
            )
        for c in coeffs:
            check_finite("camera.dist", c)
        full = tuple(float(c) for c in coeffs) + (0.0,) * (N_DIST_COEFFS - len(coeffs))
        # The radial mapping must be one-to-one over the whole image, or points
        # outside the field of view would fold back into it.
        s_fold = fold_radius_sq(full)
        if math.isfinite(s_fold):
            xs = ((-0.5 - self.cx) / self.fx, (self.width - 0.5 - self.cx) / self.fx)
            ys = ((-0.5 - self.cy) / self.fy, (self.height - 0.5 - self.cy) / self.fy)
            corner_radius = max(math.hypot(x, y) for x in xs for y in ys)
            if corner_radius >= distorted_radius(s_fold, full):
                raise ConfigError(
                    "camera.dist", "radial distortion folds over inside the image (not one-to-one); reduce k1/k2/k3"
                )
        return full  # type: ignore[return-value]
