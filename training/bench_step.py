"""Where the time of one environment step goes: camera, estimator, world, and the rest.

``python -m training.bench_step [--scenario top_observer] [--steps 5000]`` times the
whole ``env.step`` under random actions (drawn before the clock starts, as in
``moma-env bench``) and, inside it, the env's camera measurement (``env.measure``),
``MomaEstimator.update`` and ``World.step``, by wrapping those methods of the one
env it builds (instances only: nothing global is patched). With MPE2 installed it
then times MPE2 ``simple_spread`` (N=3, parallel API, random actions, as in
``moma-env bench``) in the same run and prints the per-step budget of the
benchmark's target, five times MPE2's steps per second, beside the breakdown.
Last, the ``skeleton``: the cheapest step of the same shape (the env's own pymunk
world stepped with random commands, one float32 observation array per agent
clipped to its space, and the five PettingZoo dicts; no camera, no estimator, no
rules, no reward terms), a floor that any design keeping this world and this API
in Python pays: once with the robots static as ``reset`` leaves them (their bodies
are not driven) and once with every robot mobile and driven at every substep.
A measurement, not an assertion.
"""

from __future__ import annotations

import argparse
import time

__all__ = ["mpe2_step_us", "skeleton_step_us", "step_breakdown"]

#: The speed target of ``moma-env bench``: this many times MPE2 ``simple_spread``'s joint steps per second.
TARGET_X_MPE2 = 5.0


def step_breakdown(scenario: str = "top_observer", steps: int = 5000, warmup: int = 500, seed: int = 0) -> dict[str, float]:
    """Mean microseconds per step: ``step`` and its ``camera``, ``estimator``, ``world`` and ``rest``."""
    from moma_env.env.factory import parallel_env
    from training.bench_common import time_calls

    env = parallel_env(scenario)
    env.reset(seed=seed)
    totals = {"camera": 0.0, "estimator": 0.0, "world": 0.0}

    time_calls(env, "measure", totals, "camera")

    def instrument() -> None:
        # reset() may build a new estimator or world: wrap whatever the env holds now.
        time_calls(env.estimator, "update", totals, "estimator")
        time_calls(env.world, "step", totals, "world")

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
    from training.bench_common import mpe2_reference, steps_per_second

    make_mpe2 = mpe2_reference()
    return None if make_mpe2 is None else 1e6 / steps_per_second(make_mpe2, steps, seed=seed)


def skeleton_step_us(
    scenario: str = "top_observer", steps: int = 5000, warmup: int = 500, seed: int = 0, mobile: bool = False
) -> float:
    """Mean microseconds of the skeleton step of ``scenario`` (see the module docstring).

    The world is the env's after ``reset(seed)``, where the robots start static (a
    static robot ignores its command and its body is not driven); ``mobile`` makes
    every robot mobile first. Commands (UGV body velocities up to 0.2 m/s and
    0.2 rad/s, a small UAV command when there is a UAV) are drawn from a seeded
    generator before the clock starts.
    """
    import math

    import numpy as np

    from moma_env.env.factory import parallel_env

    env = parallel_env(scenario)
    env.reset(seed=seed)
    world = env.world
    ugvs = list(world.ugv_names)
    if mobile:
        for name in ugvs:
            world.set_static(name, False)
    agents = list(env.possible_agents)
    bounds = {a: (env.observation_space(a).low, env.observation_space(a).high) for a in agents}
    sizes = {a: env.observation_space(a).shape[0] for a in agents}
    rng = np.random.default_rng(seed)
    pool = 1000
    limits = np.array([0.2, 0.2, 0.2])
    ugv_commands = [{u: rng.uniform(-limits, limits) for u in ugvs} for _ in range(pool)]
    uav_commands = [rng.uniform(-0.05, 0.05, 4) if world.has_uav else None for _ in range(pool)]

    def step(i: int) -> tuple[dict, dict, dict, dict, dict]:
        world.step(ugv_commands[i % pool], uav_commands[i % pool])
        poses = [world.ugv_pose(u) for u in ugvs]
        features: list[float] = []
        for x, y, yaw in poses:
            features += [x, y, math.cos(yaw), math.sin(yaw)]
        observations = {}
        for a in agents:
            n = sizes[a]
            values = (features * (n // len(features) + 1))[:n]
            obs = np.array(values, dtype=np.float32)
            obs.clip(*bounds[a], out=obs)
            observations[a] = obs
        reward = -sum(math.hypot(x, y) for x, y, _ in poses)
        infos = {a: {"truth": poses[0], "events": []} for a in agents}
        return observations, {a: reward for a in agents}, {a: False for a in agents}, {a: False for a in agents}, infos

    for i in range(warmup):
        step(i)
    start = time.perf_counter()
    for i in range(steps):
        step(i)
    return (time.perf_counter() - start) / steps * 1e6


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
    for mobile, robots in ((False, "robots static"), (True, "robots driven")):
        skeleton = skeleton_step_us(args.scenario, args.steps, mobile=mobile)
        print(f"{'skeleton':<10}{skeleton:8.0f} us   {robots}: world.step, observation arrays, the five dicts; no camera, estimator or rules")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
