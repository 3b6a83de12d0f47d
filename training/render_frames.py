"""Sample frames of the rendered camera, for the README.

``python -m training.render_frames --out docs`` writes:

* ``rendered_observer.png``: the observer's 720x576 frame of ``top_observer``
  (rendered backend, default textured floor, default noise) right after
  ``reset(seed=0)``, with the detected marker outlines printed to stdout;
* ``rendered_vo_floor.png``: a 160x120 frame of a robot's downward floor camera
  (0.3 m above the floor) over a fine texture, as the VO baseline sees it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from moma_env.camera import CameraConfig, FloorCamera, FloorConfig, FloorTexture
from moma_env.env.factory import parallel_env
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform, se2_to_se3
from moma_env.io import atomic_write_bytes

__all__ = ["main"]


def _write_png(path: Path, image: np.ndarray) -> None:
    ok, data = cv2.imencode(".png", image)
    if not ok:
        raise RuntimeError(f"PNG encoding of {path} failed")
    atomic_write_bytes(path, data.tobytes())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    env = parallel_env("top_observer", camera_backend="rendered")
    env.reset(seed=0)
    camera = env.cameras[env.scenario.world.uav.camera_name]
    _write_png(args.out / "rendered_observer.png", camera.last_image)
    for d in env.detections:
        print(f"observer: board {d.board_id} markers {d.marker_ids} reprojection {d.reprojection_error_px:.2f} px")

    floor = FloorTexture(FloorConfig(extent=(-1.0, -1.0, 1.0, 1.0), px_per_m=400.0, feature_size_m=0.02, contrast=0.5))
    vo_camera = FloorCamera(CameraConfig(width=160, height=120, fx=120.0), make_transform(R_BODY_CAM_DOWN, [0.2, 0.0, 0.3]), floor)
    _write_png(args.out / "rendered_vo_floor.png", vo_camera.frame(se2_to_se3(0.0, 0.0, 0.0), np.random.default_rng(0)))
    print(f"wrote {args.out / 'rendered_observer.png'} and {args.out / 'rendered_vo_floor.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
