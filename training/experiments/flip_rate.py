"""How often a board's pose comes out flipped: ``moma-env experiment flips``.

A planar board seen nearly face-on has two poses that explain its noisy corners
almost equally well: the true one and its mirror image, whose normal is the true
normal mirrored about the line of sight. This experiment measures, for one board,
how often each pose rule picks the wrong one.

Set-up (all in the camera frame C, OpenCV axes): the default robot board
(:func:`moma_env.markers.board_for_robot`) with its centre ``distance_m`` from
the camera, in a direction drawn uniformly over the central ``_IMAGE_FRACTION``
of the image (both axes); its normal ``z_M`` tilted by ``tilt`` from the line of
sight (the direction from the board's centre to the camera) towards a uniformly
random azimuth, and turned about that normal by a uniformly random in-plane yaw.
The board lies face-up in the world (``z_M`` is world up, as a robot's board is),
so the camera's attitude gives world up in C as the true normal; the board's
view declares ``up_m = (0, 0, 1)``. Corners get Gaussian noise of ``noise_px``
(through :class:`~moma_env.camera.geometric.GeometricCamera`, the env's camera,
lens distortion included). A view in which the board is not detected is drawn
again.

**Flipped**: with ``n`` the true normal in C, ``v`` the unit line of sight from the
camera to the board's centre and ``m = 2 (n . v) v - n`` the mirrored normal,
a detection is flipped when its normal ``n_hat`` (third column of its
``R_c_m``) is closer in angle to ``m`` than to ``n``. The flip rate is the
fraction of flipped detections among the views in which the rule detected the
board (the noise-free board is always detected; one lost to a failed solve is
counted in ``lost``, not as a flip).

Every rule sees the same views and the same corner noise (one Generator per
view, seeded by ``(seed, tilt index, view)``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from moma_env.camera import BoardView, CameraConfig, GeometricCamera
from moma_env.geometry import invert, make_transform, rotvec_to_matrix
from moma_env.markers import board_for_robot

__all__ = ["RULES", "FlipConfig", "flip_rates", "format_flip_table", "is_flipped", "random_view"]

#: Board centres are drawn over this central fraction of the image width and height.
_IMAGE_FRACTION = 0.6

#: The rules compared: label -> CameraConfig overrides (on ``pnp_method`` and the disambiguation).
RULES: dict[str, dict[str, object]] = {
    "PLANAR_LM min_cost": {"pnp_method": "PLANAR_LM", "pose_disambiguation": "min_cost"},
    "PLANAR_LM upright": {"pnp_method": "PLANAR_LM", "pose_disambiguation": "upright"},
    "PLANAR_LM upright, 2 deg attitude noise": {
        "pnp_method": "PLANAR_LM",
        "pose_disambiguation": "upright",
        "attitude_noise_deg": 2.0,
    },
    "IPPE min_cost": {"pnp_method": "IPPE", "pose_disambiguation": "min_cost"},
    "SQPNP min_cost": {"pnp_method": "SQPNP", "pose_disambiguation": "min_cost"},
}


@dataclasses.dataclass(frozen=True)
class FlipConfig:
    """Parameters of the flip-rate experiment.

    Attributes:
        views: views per tilt (>= 1).
        seed: seed of the views and the noise.
        tilts_deg: angles between the board normal and the line of sight (deg), each in [0, 60].
        distance_m: distance from the camera centre to the board's centre (m).
        noise_px: corner noise std (px).
    """

    views: int = 1000
    seed: int = 0
    tilts_deg: tuple[float, ...] = (5.0, 10.0, 20.0, 30.0)
    distance_m: float = 3.0
    noise_px: float = 1.0

    def __post_init__(self) -> None:
        if isinstance(self.views, bool) or not isinstance(self.views, int) or self.views < 1:
            raise ValueError(f"views must be an integer >= 1, got {self.views!r}")
        if not self.tilts_deg or any(not 0.0 <= float(t) <= 60.0 for t in self.tilts_deg):
            raise ValueError(f"tilts_deg must be angles in [0, 60] deg, got {self.tilts_deg!r}")
        if not (math.isfinite(self.distance_m) and self.distance_m > 0.0):
            raise ValueError(f"distance_m must be a finite number > 0, got {self.distance_m!r}")
        if not (math.isfinite(self.noise_px) and self.noise_px >= 0.0):
            raise ValueError(f"noise_px must be a finite number >= 0, got {self.noise_px!r}")


def random_view(camera: CameraConfig, tilt_rad: float, distance_m: float, rng: np.random.Generator) -> np.ndarray:
    """``T_c_m`` (4x4) of a board ``distance_m`` away, its normal ``tilt_rad`` from the line of sight.

    See the module docstring: random image position, tilt azimuth and in-plane yaw.
    """
    u = camera.cx + (rng.uniform(-0.5, 0.5) * _IMAGE_FRACTION) * camera.width
    w = camera.cy + (rng.uniform(-0.5, 0.5) * _IMAGE_FRACTION) * camera.height
    ray = np.array([(u - camera.cx) / camera.fx, (w - camera.cy) / camera.fy, 1.0])
    v = ray / np.linalg.norm(ray)
    # A unit vector perpendicular to v at a random azimuth: the axis of the tilt.
    a = np.cross(v, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(v, a)
    azimuth = rng.uniform(-math.pi, math.pi)
    axis = math.cos(azimuth) * a + math.sin(azimuth) * b
    n = rotvec_to_matrix(tilt_rad * axis) @ -v
    # In-plane axes: any vector perpendicular to n, turned by a random yaw about n.
    x0 = np.cross(n, a if abs(n @ a) < 0.9 else b)
    x0 /= np.linalg.norm(x0)
    x = rotvec_to_matrix(rng.uniform(-math.pi, math.pi) * n) @ x0
    R = np.column_stack([x, np.cross(n, x), n])
    return make_transform(R, distance_m * v)


def is_flipped(T_true: np.ndarray, T_est: np.ndarray) -> bool:
    """True if ``T_est``'s normal is closer in angle to the mirror of ``T_true``'s normal
    (about the line of sight to ``T_true``'s origin) than to it (both ``T_c_m``, 4x4)."""
    n = T_true[:3, 2]
    v = T_true[:3, 3] / np.linalg.norm(T_true[:3, 3])
    m = 2.0 * (n @ v) * v - n
    n_hat = T_est[:3, 2]
    return float(n_hat @ m) > float(n_hat @ n)  # closer in angle: larger cosine


def flip_rates(config: FlipConfig, rules: Sequence[str] = tuple(RULES)) -> dict:
    """Flip rate of every rule at every tilt (see the module docstring).

    Returns:
        ``{"views", "seed", "distance_m", "noise_px", "tilts_deg", "rules": {label:
        {"flip_rate": [per tilt], "flips": [per tilt], "lost": [per tilt]}}}``.
    """
    layout = board_for_robot(0)
    base = CameraConfig(noise_px=config.noise_px)
    cameras = {label: GeometricCamera("flips", dataclasses.replace(base, **RULES[label])) for label in rules}
    view_camera = GeometricCamera("flips", dataclasses.replace(base, noise_px=0.0))
    T_w_m = np.eye(4)  # the board lies face-up at the world origin: z_M is world up
    flips = {label: [0] * len(config.tilts_deg) for label in rules}
    lost = {label: [0] * len(config.tilts_deg) for label in rules}
    for k, tilt in enumerate(config.tilts_deg):
        rng_views = np.random.default_rng([config.seed, k])
        for view in range(config.views):
            while True:  # a view in which the board is detected (checked without noise)
                T_c_m = random_view(base, math.radians(tilt), config.distance_m, rng_views)
                T_w_c = T_w_m @ invert(T_c_m)
                board = BoardView(0, layout, T_w_m, up_m=np.array([0.0, 0.0, 1.0]))
                if view_camera.measure(T_w_c, [board], 0.0, rng_views):
                    break
            for label, camera in cameras.items():
                detections = camera.measure(T_w_c, [board], 0.0, np.random.default_rng([config.seed, k, view]))
                if not detections:
                    lost[label][k] += 1
                elif is_flipped(T_c_m, detections[0].T_c_m):
                    flips[label][k] += 1
    return {
        "views": config.views,
        "seed": config.seed,
        "distance_m": config.distance_m,
        "noise_px": config.noise_px,
        "tilts_deg": [float(t) for t in config.tilts_deg],
        "rules": {
            label: {
                "flips": f,
                "lost": lost[label],
                "flip_rate": [c / max(1, config.views - m) for c, m in zip(f, lost[label])],
            }
            for label, f in flips.items()
        },
    }


def format_flip_table(result: dict) -> str:
    """The result of :func:`flip_rates` as a Markdown table (flip rates in %)."""
    tilts = result["tilts_deg"]
    head = "| rule | " + " | ".join(f"{t:g} deg" for t in tilts) + " |"
    rule = "|---|" + "---:|" * len(tilts)
    rows = [
        f"| {label} | " + " | ".join(f"{100.0 * r:.1f} %" for r in data["flip_rate"]) + " |"
        for label, data in result["rules"].items()
    ]
    title = (
        f"Flipped poses of a board at {result['distance_m']:g} m with {result['noise_px']:g} px corner noise, "
        f"{result['views']} views per tilt (seed {result['seed']}); tilt = angle between the board normal and the line of sight"
    )
    return "\n".join([title, "", head, rule, *rows])
