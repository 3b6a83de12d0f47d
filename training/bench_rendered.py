"""Benchmark of the rendered camera in the environment (part of ``moma-env bench``).

``top_observer`` with ``camera_backend="rendered"``: the observer's PAL camera
(720x576, default lens) draws every frame (floor, boards, blur, sensor noise of
std ``RenderConfig.noise_std``) and runs ``cv2.aruco.ArucoDetector`` on it.
Random actions in the ``switching`` mode (the observer's tracking controller
flies it, so it moves and the floor is re-drawn nearly every frame). Reported
per floor (textured all over, the env's default, and plain): joint steps per
second, and per step the mean wall-clock time of the whole step, of drawing
the image and of the detector itself (``RenderedCamera.last_render_s`` and
``last_detect_s``, measured in the same run), and the ratio step / detection.
"""

from __future__ import annotations

import time

__all__ = ["bench_rendered", "format_rendered"]

#: Floors of the benchmark: name -> EnvConfig.floor keywords (None: the default textured floor).
FLOORS = {"textured": None, "plain": {"textured": ()}}


def bench_rendered(steps: int, seed: int = 0) -> list[dict]:
    """One row per floor: steps/s and the mean step, render and detection times (ms)."""
    from moma_env.camera import RenderConfig
    from moma_env.env.factory import parallel_env

    rows = []
    for floor_name, floor in FLOORS.items():
        env = parallel_env("top_observer", camera_backend="rendered", floor=floor)
        env.reset(seed=seed)
        for agent in env.possible_agents:
            env.action_space(agent).seed(seed)
        camera = env._cameras[env.scenario.world.uav.camera_name]
        render_s = detect_s = 0.0
        start = time.perf_counter()
        for _ in range(steps):
            if not env.agents:
                env.reset()
            env.step({a: env.action_space(a).sample() for a in env.agents})
            render_s += camera.last_render_s
            detect_s += camera.last_detect_s
        elapsed = time.perf_counter() - start
        env.close()
        cfg = camera.config
        rows.append(
            {
                "env": "top_observer",
                "floor": floor_name,
                "image": f"{cfg.width}x{cfg.height}",
                "noise_std": RenderConfig().noise_std if env.config.render is None else env.config.render.noise_std,
                "steps": steps,
                "steps_per_s": steps / elapsed,
                "step_ms": 1e3 * elapsed / steps,
                "render_ms": 1e3 * render_s / steps,
                "detect_ms": 1e3 * detect_s / steps,
                "step_over_detect": elapsed / detect_s if detect_s > 0 else float("nan"),
            }
        )
    return rows


def format_rendered(rows: list[dict]) -> str:
    """The rendered-camera table."""
    lines = [
        f"{'rendered camera':<16}{'floor':<10}{'image':<9}{'noise':>6}{'steps/s':>9}{'step ms':>9}"
        f"{'render ms':>10}{'detect ms':>10}{'step/detect':>12}",
        "-" * 91,
    ]
    for r in rows:
        lines.append(
            f"{r['env']:<16}{r['floor']:<10}{r['image']:<9}{r['noise_std']:>6g}{r['steps_per_s']:>9.0f}{r['step_ms']:>9.2f}"
            f"{r['render_ms']:>10.2f}{r['detect_ms']:>10.2f}{r['step_over_detect']:>12.2f}"
        )
    if rows:
        lines.append(f"({rows[0]['steps']} random-action steps per row, switching mode; detection = ArucoDetector.detectMarkers)")
    return "\n".join(lines)
