"""Benchmark of the rendered camera in the environment (part of ``moma-env bench``).

``top_observer`` with ``camera_backend="rendered"``: the observer's PAL camera
(720x576, default lens) draws every frame (floor, boards, blur, sensor noise of
std ``RenderConfig.noise_std``) and runs ``cv2.aruco.ArucoDetector`` on it.
Random actions in the ``switching`` mode (the observer's tracking controller
flies it, so it moves and the floor is re-drawn nearly every frame). Rows: the
textured floor (the env's default), a plain floor, the textured floor with
``RenderConfig.floor_reuse_px = 0.25``, and the textured floor without noise.
Reported per row: joint steps per second, and per step the mean wall-clock
time of the whole step, of drawing the image and of the detector itself
(``RenderedCamera.last_render_s`` and ``last_detect_s``, measured in the same
run), and the ratio step / detection. With ``rounds`` > 1 every variant runs
once per round, rounds interleaved, and its row is its fastest round (the
step, drawing and detection times of that one run).
"""

from __future__ import annotations

__all__ = ["bench_rendered", "format_rendered"]

#: Rows of the benchmark: (floor name, EnvConfig.floor keywords, EnvConfig.render keywords);
#: None is the default (textured floor; RenderConfig defaults).
VARIANTS = (
    ("textured", None, None),
    ("plain", {"textured": ()}, None),
    ("textured", None, {"floor_reuse_px": 0.25}),
    ("textured", None, {"noise_std": 0.0}),
)


class _CameraTimes:
    """A parallel env whose ``step`` adds up its camera's render and detection times (s)."""

    def __init__(self, env, camera) -> None:
        self.env, self.camera = env, camera
        self.render_s = self.detect_s = 0.0

    def step(self, actions):
        out = self.env.step(actions)
        self.render_s += self.camera.last_render_s
        self.detect_s += self.camera.last_detect_s
        return out

    def __getattr__(self, name):
        return getattr(self.env, name)


def bench_rendered(steps: int, seed: int = 0, rounds: int = 1) -> list[dict]:
    """One row per variant: steps/s and the mean step, render and detection times (ms)
    of its fastest round (``rounds_steps_per_s``: every round's rate).

    Steps are timed by :func:`training.bench.steps_per_second` (random actions
    drawn before the clock starts, episodes reset when they end).
    """
    from training.bench import best_of_rounds

    return best_of_rounds([lambda variant=variant: _rendered_row(variant, steps, seed) for variant in VARIANTS], rounds)


def _rendered_row(variant: tuple, steps: int, seed: int) -> dict:
    """One timed run of one variant (see :data:`VARIANTS`)."""
    from moma_env.camera import RenderConfig
    from moma_env.env.factory import parallel_env
    from training.bench import steps_per_second

    floor_name, floor, render = variant
    env = parallel_env("top_observer", camera_backend="rendered", floor=floor, render=render)
    timed = _CameraTimes(env, env._cameras[env.scenario.world.uav.camera_name])
    rate = steps_per_second(lambda: timed, steps, seed=seed)
    cfg = timed.camera.config
    render_cfg = env.config.render or RenderConfig()
    return {
        "env": "top_observer",
        "floor": floor_name,
        "floor_reuse_px": render_cfg.floor_reuse_px,
        "image": f"{cfg.width}x{cfg.height}",
        "noise_std": render_cfg.noise_std,
        "steps": steps,
        "steps_per_s": rate,
        "step_ms": 1e3 / rate,
        "render_ms": 1e3 * timed.render_s / steps,
        "detect_ms": 1e3 * timed.detect_s / steps,
        "step_over_detect": steps / rate / timed.detect_s if timed.detect_s > 0 else float("nan"),
    }


def format_rendered(rows: list[dict]) -> str:
    """The rendered-camera table."""
    lines = [
        f"{'rendered camera':<16}{'floor':<10}{'reuse px':>9}{'image':>9}{'noise':>6}{'steps/s':>9}{'step ms':>9}"
        f"{'render ms':>10}{'detect ms':>10}{'step/detect':>12}",
        "-" * 100,
    ]
    for r in rows:
        lines.append(
            f"{r['env']:<16}{r['floor']:<10}{r['floor_reuse_px']:>9g}{r['image']:>9}{r['noise_std']:>6g}"
            f"{r['steps_per_s']:>9.0f}{r['step_ms']:>9.2f}"
            f"{r['render_ms']:>10.2f}{r['detect_ms']:>10.2f}{r['step_over_detect']:>12.2f}"
        )
    if rows:
        lines.append(
            f"({rows[0]['steps']} random-action steps per row, best of {len(rows[0].get('rounds_steps_per_s', [0]))} "
            "interleaved rounds, switching mode; detection = ArucoDetector.detectMarkers)"
        )
    return "\n".join(lines)
