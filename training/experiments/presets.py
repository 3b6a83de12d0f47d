"""Named, validated settings of the experiments' sensing: ``--preset NAME``.

A preset fixes what the paper's hardware fixed: the observer camera (resolution,
focal length, distortion, corner noise), its image pipeline when rendered, the
flying altitude, the boards, and whether the UGVs are estimated upright on the
floor or in full 6-DoF as the paper's system did. It leaves the experiment
(square or line, observer kind, runs) alone: :meth:`ExperimentPreset.apply`
returns a copy of an experiment's configuration with the preset's fields.

``default`` is the experiments' own defaults (geometric camera, 0.5 px corner
noise, altitude chosen by the tracking controller, planar UGVs); ``paper``
models the authors' set-up (see :data:`PAPER` and the README for how it was
chosen and what it measures).

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

from moma_env.camera import CAMERA_BACKENDS, CameraConfig, RenderConfig
from moma_env.config import ConfigError, check_bool, check_choice, check_positive
from moma_env.markers import BoardLayout
from training.experiments.leapfrog_run import LeapfrogConfig

__all__ = ["ExperimentPreset", "DEFAULT", "PAPER", "PRESETS", "get_preset"]

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
    """

    name: str
    description: str
    camera_backend: str = "geometric"
    camera: CameraConfig = field(default_factory=CameraConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    altitude: float | None = None
    board: BoardLayout = field(default_factory=BoardLayout)
    planar_ugvs: bool = True

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
        )


#: The experiments' own defaults.
DEFAULT = ExperimentPreset(name="default", description="geometric camera, 0.5 px corner noise, planar UGVs")

#: The authors' set-up (section IV, DESIGN.md section 2); README "The paper preset"
#: says how it was chosen and what it measures.
PAPER = ExperimentPreset(
    name="paper",
    description=(
        "Ar.Drone 2.0 with an FPV analogue camera: PAL 720x576 through the video link (interlaced fields 20 ms apart, "
        "1 px blur, noise 6 gray levels), 2.5 m altitude, 34 cm boards, full 6-DoF estimate"
    ),
    camera_backend="rendered",
    # A 2.8 mm FPV lens on a 1/3" CCD (4.8 mm wide): 81 deg horizontal field of view, f = 420 px at 720 px.
    camera=CameraConfig(width=720, height=576, fx=420.0, dist=(-0.05, 0.01, 0.0, 0.0, 0.0), noise_px=0.5),
    # The analogue link: composite video's ~5 MHz luminance bandwidth softens the
    # 720 px line (about 1 px of blur), the 5.8 GHz link adds noise (SNR ~ 32 dB:
    # 6 gray levels), and PAL's two fields are exposed 20 ms apart.
    render=RenderConfig(blur_sigma_px=1.0, noise_std=6.0, interlaced=True, field_period_s=0.02, corner_refinement="SUBPIX"),
    altitude=2.5,
    board=BoardLayout(marker_size=0.16, gap=0.02),
    planar_ugvs=False,
)

#: Every preset by name.
PRESETS = {p.name: p for p in (DEFAULT, PAPER)}


def get_preset(name: str) -> ExperimentPreset:
    """The preset called ``name``; ConfigError naming the known ones otherwise."""
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise ConfigError("preset", f"unknown preset {name!r}; known: {', '.join(sorted(PRESETS))}") from None
