"""Image formation after the optics: blur, contrast and brightness, sensor noise.

Every random draw comes from the caller's numpy Generator (never cv2's global
RNG). Noise is drawn as one random byte per pixel (the bytes of
``Generator.bytes``) mapped through a table of the 256 quantiles of a
Gaussian, ``noise_std * Phi^-1((k + 0.5) / 256)``: exact inverse-CDF sampling
of a Gaussian quantised to 256 levels (truncated at about +-2.66 sigma), five
times cheaper than ``standard_normal`` on a PAL frame.

Read-out speed: the output gray level depends only on the scene's gray level
and the pixel's random byte, so contrast, brightness, noise and the rounding
to uint8 are one 256 x 256 table (built with the same OpenCV arithmetic as the
step-by-step version, hence the same bytes), applied in one compiled pass. The
bytes of a PCG64 generator are taken straight from its 64-bit outputs, the
same bytes ``Generator.bytes`` would give and the same state after, at a
fraction of its cost (see :func:`noise_bytes`).
"""

from __future__ import annotations

import sys
from statistics import NormalDist

import cv2
import numba
import numpy as np

from moma_env.camera.render_config import RenderConfig

__all__ = ["SensorModel", "noise_bytes"]

#: Bit generators whose ``random_raw`` yields 64 random bits per value, in the order
#: ``Generator.bytes`` consumes them (low 32 bits first).
_RAW64_BIT_GENERATORS = (np.random.PCG64, np.random.PCG64DXSM)


def noise_bytes(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random bytes (uint8, (n,)) from ``rng``: exactly ``Generator.bytes(n)``,
    leaving ``rng`` in the same state.

    ``Generator.bytes`` draws 32-bit integers and keeps their little-endian bytes;
    a PCG64 generator serves those as the low then the high half of each 64-bit
    output. So when ``n`` is a multiple of 8, no half of an earlier output is
    pending and the machine is little-endian, the bytes of ``random_raw(n // 8)``
    are the same bytes, about five times faster. Otherwise ``Generator.bytes``.
    """
    bit_generator = rng.bit_generator
    if n % 8 == 0 and sys.byteorder == "little" and isinstance(bit_generator, _RAW64_BIT_GENERATORS):
        if not bit_generator.state["has_uint32"]:
            return bit_generator.random_raw(n // 8).view(np.uint8)
    return np.frombuffer(rng.bytes(n), dtype=np.uint8)


@numba.njit(cache=True)
def _read_out_kernel(image: np.ndarray, draws: np.ndarray, table: np.ndarray) -> None:
    """``image[i, j] = table[256 * image[i, j] + draws[i * width + j]]`` in place (uint8;
    ``table`` flat, 65536 entries)."""
    rows, cols = image.shape
    for i in range(rows):
        row = image[i]
        base = i * cols
        for j in range(cols):
            row[j] = table[(np.int64(row[j]) << 8) | np.int64(draws[base + j])]


class SensorModel:
    """Turns a rendered scene (uint8) into the camera's output image (uint8).

    Args:
        config: blur, contrast, brightness and noise of the camera.
    """

    def __init__(self, config: RenderConfig) -> None:
        self.config = config
        levels = np.arange(256, dtype=float)
        gain = config.contrast * (levels - 128.0) + 128.0 + config.brightness
        self._gain_lut = np.clip(np.rint(gain), 0, 255).astype(np.uint8)
        self._identity_gain = bool(np.array_equal(self._gain_lut, levels.astype(np.uint8)))
        # OpenCV's own kernel size for a sigma on 8-bit images: round(6 sigma + 1), made odd.
        self._ksize = int(round(6.0 * config.blur_sigma_px + 1.0)) | 1
        self._kernel_radius = self._ksize // 2
        unit = NormalDist()
        quantiles = [unit.inv_cdf((k + 0.5) / 256.0) for k in range(256)]
        self._noise_lut = (config.noise_std * np.array(quantiles)).astype(np.float32)
        # table[256 * level + byte]: the read-out of gray level ``level`` with random byte ``byte``,
        # computed with the same OpenCV calls (gain LUT, then a saturating add of the
        # float noise) as a frame read out step by step.
        grid = np.broadcast_to(np.arange(256, dtype=np.uint8)[:, None], (256, 256))
        draws = np.ascontiguousarray(np.broadcast_to(np.arange(256, dtype=np.uint8), (256, 256)))
        table = cv2.add(cv2.LUT(np.ascontiguousarray(grid), self._gain_lut), cv2.LUT(draws, self._noise_lut), dtype=cv2.CV_8U)
        self._readout_table = np.ascontiguousarray(table).reshape(-1)  # flat: one index per pixel

    def apply(self, scene: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The output image of ``scene`` (uint8, (height, width); modified in place and returned):
        :meth:`blur`, then :meth:`read_out`."""
        return self.read_out(self.blur(scene), rng)

    def blur(self, scene: np.ndarray, window: tuple[int, int, int, int] | None = (0, 0, 1 << 30, 1 << 30)) -> np.ndarray:
        """The optics' blur of ``scene`` (in place; returned). Comes before interlacing:
        each field is an image of the (blurred) scene at its own time.

        ``window`` ``(x0, y0, x1, y1)`` (px, end exclusive): the scene is one
        gray level outside it (None: everywhere), where the blur changes
        nothing; only the window grown by the kernel's radius is filtered,
        with the same result as filtering the whole image.
        """
        sigma = self.config.blur_sigma_px
        if sigma <= 0.0 or window is None:
            return scene
        h, w = scene.shape
        r = self._kernel_radius
        x0, y0 = max(window[0] - r, 0), max(window[1] - r, 0)
        x1, y1 = min(window[2] + r, w), min(window[3] + r, h)
        if x0 >= x1 or y0 >= y1:
            return scene
        if (x0, y0, x1, y1) == (0, 0, w, h):
            cv2.GaussianBlur(scene, (self._ksize, self._ksize), sigma, dst=scene, borderType=cv2.BORDER_REPLICATE)
        else:
            part = scene[y0:y1, x0:x1]
            part[...] = cv2.GaussianBlur(part, (self._ksize, self._ksize), sigma, borderType=cv2.BORDER_REPLICATE)
        return scene

    def read_out(self, image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Contrast, brightness and sensor noise applied to ``image`` (uint8, (height, width),
        C-contiguous; in place; returned)."""
        if self.config.noise_std > 0.0:
            _read_out_kernel(image, noise_bytes(rng, image.size), self._readout_table)
        elif not self._identity_gain:
            cv2.LUT(image, self._gain_lut, dst=image)
        return image
