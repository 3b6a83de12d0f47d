"""Where the time of one environment step goes: camera, estimator, world, and the rest.

``python -m training.bench_step [--scenario top_observer] [--steps 5000]`` times the
whole ``env.step`` under random actions (drawn before the clock starts, as in
``moma-env bench``) and, inside it, the calls of ``GeometricCamera.measure``,
``MomaEstimator.update`` and ``World.step``, by wrapping those methods of the one
env it builds (instances only: nothing global is patched). With MPE2 installed it
then times MPE2 ``simple_spread`` (N=3, parallel API, random actions, as in
``moma-env bench``) in the same run and prints the per-step budget of the
benchmark's target, five times MPE2's steps per second, beside the breakdown.
A measurement, not an assertion.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

__all__ = ["mpe2_step_us", "step_breakdown"]

#: The speed target of ``moma-env bench``: this many times MPE2 ``simple_spread``'s joint steps per second.
TARGET_X_MPE2 = 5.0


def _timed(owner: object, method: str, totals: dict[str, float], key: str) -> None:
    """Replace ``owner.method`` (on the instance) by a wrapper adding its wall time to
    ``totals[key]``; an instance already wrapped is left alone."""
    inner: Callable = getattr(owner, method)
    if getattr(inner, "_timed", False):
        return

    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            totals[key] += time.perf_counter() - start

    wrapper._timed = True  # type: ignore[attr-defined]
    setattr(owner, method, wrapper)


def step_breakdown(scenario: str = "top_observer", steps: int = 5000, warmup: int = 500, seed: int = 0) -> dict[str, float]:
    """Mean microseconds per step: ``step`` and its ``camera``, ``estimator``, ``world`` and ``rest``."""
    from moma_env.env.factory import parallel_env

    env = parallel_env(scenario)
    env.reset(seed=seed)
    totals = {"camera": 0.0, "estimator": 0.0, "world": 0.0}

    def instrument() -> None:
        # reset() may build a new estimator or world: wrap whatever the env holds now.
        for camera in env._cameras.values():
            _timed(camera, "measure", totals, "camera")
        _timed(env.estimator, "update", totals, "estimator")
        _timed(env.world, "step", totals, "world")

    instrument()
    agents = list(env.possible_agents)
    for agent in agents:
        env.action_space(agent).seed(seed)
    joint = [{a: env.action_space(a).sample() for a in agents} for _ in range(1000)]

    def run(n: int) -> float:
        start = time.perf_counter()
        for i in range(n):
            if not env.agents:
                env.reset()
                instrument()
            actions = joint[i % len(joint)]
            env.step({a: actions[a] for a in env.agents})
        return time.perf_counter() - start

    run(warmup)
    for key in totals:
        totals[key] = 0.0
    elapsed = run(steps)
    out = {"step": elapsed / steps * 1e6}
    out.update({key: value / steps * 1e6 for key, value in totals.items()})
    out["rest"] = out["step"] - out["camera"] - out["estimator"] - out["world"]
    return out


def mpe2_step_us(steps: int = 5000, seed: int = 0) -> float | None:
    """Mean microseconds per joint step of MPE2 ``simple_spread`` (N=3, parallel API,
    random actions drawn before the clock starts); None if mpe2 is not installed."""
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        return None
    from training.bench import steps_per_second

    return 1e6 / steps_per_second(lambda: simple_spread_v3.parallel_env(N=3), steps, seed=seed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Cost breakdown of one environment step (geometric camera).")
    parser.add_argument("--scenario", default="top_observer")
    parser.add_argument("--steps", type=int, default=5000)
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error("--steps must be >= 1")
    result = step_breakdown(args.scenario, args.steps)
    for key, value in result.items():
        print(f"{key:<10}{value:8.0f} us")
    mpe2 = mpe2_step_us(args.steps)
    if mpe2 is None:
        print("(mpe2 not installed: no target budget)")
    else:
        print(f"{'mpe2':<10}{mpe2:8.0f} us   MPE2 simple_spread N=3, same run")
        print(f"{'budget':<10}{mpe2 / TARGET_X_MPE2:8.0f} us   per step at {TARGET_X_MPE2:g}x MPE2's steps/s (the target)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
