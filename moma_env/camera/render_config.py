"""Configuration of the rendered camera: image formation and the ArUco detector.

Defaults model the paper's observer, an analogue PAL camera: slightly soft
(blur), noisy, with ArUco's sub-pixel corner refinement. Interlacing (the odd
field exposed one field period before the even one) is off by default.
"""

from __future__ import annotations

from dataclasses import dataclass

from moma_env.config import ConfigError, check_bool, check_choice, check_count, check_non_negative, check_positive, check_range

__all__ = ["CORNER_REFINEMENTS", "RenderConfig"]

#: ArUco corner refinement methods (names of ``cv2.aruco.CORNER_REFINE_*`` without the prefix).
CORNER_REFINEMENTS = ("NONE", "SUBPIX", "CONTOUR", "APRILTAG")


@dataclass(frozen=True)
class RenderConfig:
    """How the rendered camera forms and reads its image.

    Attributes:
        blur_sigma_px: standard deviation of the Gaussian optical blur (px); 0: none.
        noise_std: standard deviation of the additive sensor noise (gray levels);
            Gaussian, sampled by inverse CDF from one random byte per pixel
            (256 quantiles, so truncated at about 2.7 sigma); 0: none.
        brightness: offset added to every gray level.
        contrast: gain about mid-gray 128 (1: unchanged).
        interlaced: PAL interlacing: the odd rows are the scene one field period
            earlier (poses interpolated from the previous frame).
        field_period_s: time between the two fields (s); 0.02 for PAL.
        corner_refinement: ArUco corner refinement, one of :data:`CORNER_REFINEMENTS`.
        quiet_zone_m: white paper around the outer markers of a board (m).
        bit_px: board raster pixels per marker bit (finest pyramid level).
        paper_gray, ink_gray: gray levels of the board's white paper and black ink.
        occluder_gray: gray level painted over a marker whose line of sight is blocked.
        floor_reuse_px: the floor view is drawn again only when the camera has
            moved enough to shift it by more than this (px) since it was drawn;
            0 redraws it whenever the pose changes at all. Boards are drawn
            every frame at their exact place whatever this is.
    """

    blur_sigma_px: float = 0.7
    noise_std: float = 3.0
    brightness: float = 0.0
    contrast: float = 1.0
    interlaced: bool = False
    field_period_s: float = 0.02
    corner_refinement: str = "SUBPIX"
    quiet_zone_m: float = 0.02
    bit_px: int = 16
    paper_gray: int = 235
    ink_gray: int = 25
    occluder_gray: int = 70
    floor_reuse_px: float = 0.0

    def __post_init__(self) -> None:
        check_non_negative("render.blur_sigma_px", self.blur_sigma_px)
        check_non_negative("render.noise_std", self.noise_std)
        check_range("render.brightness", self.brightness, -255.0, 255.0)
        check_positive("render.contrast", self.contrast)
        check_bool("render.interlaced", self.interlaced)
        check_positive("render.field_period_s", self.field_period_s)
        check_choice("render.corner_refinement", self.corner_refinement, CORNER_REFINEMENTS)
        check_non_negative("render.quiet_zone_m", self.quiet_zone_m)
        check_count("render.bit_px", self.bit_px, minimum=2)
        check_non_negative("render.floor_reuse_px", self.floor_reuse_px)
        for name in ("paper_gray", "ink_gray", "occluder_gray"):
            check_count(f"render.{name}", getattr(self, name), minimum=0)
            check_range(f"render.{name}", getattr(self, name), 0, 255)
        if self.paper_gray <= self.ink_gray:
            raise ConfigError("render.paper_gray", f"must exceed ink_gray={self.ink_gray}, got {self.paper_gray}")
