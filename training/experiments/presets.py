"""Named, validated settings of the experiments' sensing: ``--preset NAME``.

A preset fixes what the paper's hardware fixed: the observer camera (resolution,
focal length, distortion, corner noise), its image pipeline when rendered, the
flying altitude, the boards, whether the UGVs are estimated upright on the
floor or in full 6-DoF as the paper's system did, and what the floor looks
like where nothing is printed on it (perfectly plain, or a real floor's grain,
seams and specks). It leaves the experiment
(square or line, observer kind, runs) alone: :meth:`ExperimentPreset.apply`
returns a copy of an experiment's configuration with the preset's fields.

``default`` is the experiments' own defaults (geometric camera, 0.5 px corner
noise, altitude chosen by the tracking controller, planar UGVs, a perfectly
plain floor outside the textured regions); ``paper`` models the authors'
set-up (see :data:`PAPER` and ``docs/paper_preset.md`` for where its numbers
come from and what it measures).

Usable from Python::

    from training.experiments.presets import get_preset
    from training.experiments.square import SquareConfig, run_square
    config = get_preset("paper").apply(SquareConfig(observer="handheld"))
    run = run_square(config, seed=0)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TypeVar

from moma_env.camera import CAMERA_BACKENDS, CameraConfig, FloorGrainConfig, RenderConfig
from moma_env.config import ConfigError, check_bool, check_choice, check_positive
from moma_env.markers import BoardLayout
from training.experiments.leapfrog_run import LeapfrogConfig

__all__ = ["ExperimentPreset", "DEFAULT", "PAPER", "PAPER_CAMERA", "PRESETS", "get_preset"]

C = TypeVar("C", bound=LeapfrogConfig)


@dataclass(frozen=True)
class ExperimentPreset:
    """The sensing settings of an experiment, under a name.

    Attributes:
        name: the preset's name (``--preset NAME``).
        description: one line on what it models.
        camera_backend: ``"geometric"`` or ``"rendered"`` (overridable with ``--camera``).
        camera: the observer camera (intrinsics, distortion, corner noise of the
            geometric backend).
        render: the observer's image formation with the rendered backend (blur,
            noise, interlacing, corner refinement).
        altitude: fixed flying altitude of the observer (m); None lets the
            tracking controller choose it.
        board: the robots' board layout (marker size and gap, m).
        planar_ugvs: estimate the UGVs upright on the floor (True) or in full
            6-DoF (False, as the paper's system).
        floor_grain: the weak texture of the floor outside the experiment's
            textured regions (rendered cameras only); None: perfectly plain.
    """

    name: str
    description: str
    camera_backend: str = "geometric"
    camera: CameraConfig = field(default_factory=CameraConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    altitude: float | None = None
    board: BoardLayout = field(default_factory=BoardLayout)
    planar_ugvs: bool = True
    floor_grain: FloorGrainConfig | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ConfigError("preset.name", f"must be a non-empty identifier, got {self.name!r}")
        if not isinstance(self.description, str) or not self.description:
            raise ConfigError("preset.description", "must be a non-empty string")
        check_choice("preset.camera_backend", self.camera_backend, CAMERA_BACKENDS)
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("preset.camera", f"must be a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.render, RenderConfig):
            raise ConfigError("preset.render", f"must be a RenderConfig, got {type(self.render).__name__}")
        if self.altitude is not None:
            check_positive("preset.altitude", self.altitude)
        if not isinstance(self.board, BoardLayout):
            raise ConfigError("preset.board", f"must be a BoardLayout, got {type(self.board).__name__}")
        check_bool("preset.planar_ugvs", self.planar_ugvs)
        if self.floor_grain is not None and not isinstance(self.floor_grain, FloorGrainConfig):
            raise ConfigError("preset.floor_grain", f"must be a FloorGrainConfig or None, got {type(self.floor_grain).__name__}")

    def apply(self, config: C, camera_backend: str | None = None) -> C:
        """``config`` with this preset's sensing (validated again by the experiment's config).

        Args:
            config: an experiment's configuration (square, line).
            camera_backend: overrides the preset's backend if given.
        """
        return dataclasses.replace(
            config,
            camera_backend=self.camera_backend if camera_backend is None else camera_backend,
            camera=self.camera,
            render=self.render,
            altitude=self.altitude,
            board=self.board,
            planar_ugvs=self.planar_ugvs,
            floor=dataclasses.replace(config.floor, grain=self.floor_grain),
        )


#: The experiments' own defaults.
DEFAULT = ExperimentPreset(name="default", description="geometric camera, 0.5 px corner noise, planar UGVs")

#: The UAV's external camera as the authors calibrated it: tud_momana,
#: ``cfg/camera_info/ardrone_ext_cam.yaml`` (720x576, plumb_bob). Non-square
#: pixels (fy / fx = 1.067: the PAL frame digitised at 720 px per line), the
#: principal point 21 px left of and 30 px above the image centre, and a strong
#: barrel distortion (k1 = -0.42, k2 = 0.15: 89 x 65 deg field of view through
#: the principal point; the radial mapping does not fold anywhere, as
#: 9 k1^2 < 20 k2).
PAPER_CAMERA = CameraConfig(
    width=720,
    height=576,
    fx=492.856172,
    fy=526.006429,
    cx=338.263513,
    cy=257.626108,
    dist=(-0.419143, 0.152472, 0.000282, -0.001497, 0.0),
    noise_px=0.5,
)

#: The authors' set-up (section IV, DESIGN.md section 2); ``docs/paper_preset.md``
#: says where the numbers come from and what the preset measures.
PAPER = ExperimentPreset(
    name="paper",
    description=(
        "Ar.Drone 2.0 with the authors' calibrated external camera (tud_momana ardrone_ext_cam.yaml: 720x576, "
        "fx 492.9 / fy 526.0 px, k1 -0.419), PAL video link (interlaced fields 20 ms apart, 1 px blur, noise 6 gray "
        "levels), 2.5 m altitude, 34 cm boards, full 6-DoF estimate, a vinyl-tiled lab floor (grain, seams, specks)"
    ),
    camera_backend="rendered",
    camera=PAPER_CAMERA,
    # The analogue link: composite video's ~5 MHz luminance bandwidth softens the
    # 720 px line (about 1 px of blur), the 5.8 GHz link adds noise (SNR ~ 32 dB:
    # 6 gray levels), and PAL's two fields are exposed 20 ms apart.
    render=RenderConfig(blur_sigma_px=1.0, noise_std=6.0, interlaced=True, field_period_s=0.02, corner_refinement="SUBPIX"),
    altitude=2.5,
    board=BoardLayout(marker_size=0.16, gap=0.02),
    planar_ugvs=False,
    # The untextured half of the square is a real lab floor, not one gray level:
    # 3 gray levels of grain, 30 cm tiles with 1.5 mm seams, about one speck per dm^2
    # (see moma_env.camera.floor_grain for why those amplitudes and scales).
    floor_grain=FloorGrainConfig(),
)

#: Every preset by name.
PRESETS = {p.name: p for p in (DEFAULT, PAPER)}


def get_preset(name: str) -> ExperimentPreset:
    """The preset called ``name``; ConfigError naming the known ones otherwise."""
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise ConfigError("preset", f"unknown preset {name!r}; known: {', '.join(sorted(PRESETS))}") from None
