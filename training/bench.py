"""Benchmarks: environment steps per second against MPE2, and memory over long runs.

``moma-env bench`` runs, on this machine and in the same process:

* joint steps per second of every configuration (random actions sampled from the
  action spaces, episodes reset when they end, geometric camera), in both action
  modes;
* MPE2 ``simple_spread`` (N=3, parallel API, random actions) as the reference;
* the resident memory of ``top_observer`` sampled over a long run (``--memory-steps``);
* the rendered camera in ``top_observer`` (``--rendered-steps``, see
  :mod:`training.bench_rendered`): steps per second at 720x576 with noise and
  the detector's own time per frame, measured in the same run.
* PPO training frames per second on the switching task (``--train-steps``; needs the
  ``train`` extra; :mod:`training.train.bench`).

Rounds (``--rounds``): the step rates (MPE2, every configuration, the rendered
rows) are measured in several interleaved rounds, each round running every row
once, and each row reports its best round, the standard estimate of a rate on a
machine shared with other work (a slower round is slowed by something else,
never by the code; interleaving spreads a slow period over every row, so the
ratios to MPE2 compare like with like). Every round's rate is kept in the
JSON output.

The numbers are measurements, not assertions: tests never time anything.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from training.bench_common import best_of_rounds, mpe2_reference, resident_mb, steps_per_second, time_calls

__all__ = [
    "steps_per_second",
    "best_of_rounds",
    "mpe2_reference",
    "bench_configurations",
    "memory_profile",
    "resident_mb",
    "time_calls",
]


def bench_configurations(steps: int, rounds: int = 1, include_mpe2: bool = False) -> list[dict]:
    """Steps per second of every configuration in both action modes (and of MPE2
    ``simple_spread`` N=3 first, if ``include_mpe2`` and mpe2 is installed), in
    interleaved rounds (:func:`best_of_rounds`)."""
    from moma_env.env.factory import parallel_env
    from moma_env.scenarios import CONFIGURATIONS

    makers: list[tuple[str, str, Callable[[], Any]]] = []
    make_mpe2 = mpe2_reference() if include_mpe2 else None
    if make_mpe2 is not None:
        makers.append(("mpe2 simple_spread", "N=3", make_mpe2))
    for name in CONFIGURATIONS:
        for mode in ("switching", "velocity"):
            makers.append((name, mode, lambda n=name, m=mode: parallel_env(n, action_mode=m)))
    measures = [
        lambda name=name, mode=mode, make_env=make_env: {
            "env": name, "action_mode": mode, "steps_per_s": steps_per_second(make_env, steps)
        }
        for name, mode, make_env in makers
    ]
    return best_of_rounds(measures, rounds)


def memory_profile(steps: int, samples: int = 10) -> list[tuple[int, float]]:
    """(step, resident MB) of ``top_observer`` (switching, random actions) at ``samples`` points."""
    from moma_env.env.factory import parallel_env

    env = parallel_env("top_observer")
    env.reset(seed=0)
    points = [(0, resident_mb())]
    every = max(1, steps // samples)
    for k in range(1, steps + 1):
        if not env.agents:
            env.reset()
        env.step({a: env.action_space(a).sample() for a in env.agents})
        if k % every == 0:
            points.append((k, resident_mb()))
    env.close()
    return points


def run_bench(
    steps: int,
    memory_steps: int,
    rendered_steps: int = 0,
    rendered_only: bool = False,
    train_steps: int = 0,
    rounds: int = 1,
) -> dict:
    """Everything ``moma-env bench`` reports, as a dict (``rendered_only``: just the rendered camera)."""
    from training.bench_rendered import bench_rendered

    rows = [] if rendered_only else bench_configurations(steps, rounds, include_mpe2=True)
    mpe_rows = [row for row in rows if row["env"] == "mpe2 simple_spread"]
    rows = [row for row in rows if row["env"] != "mpe2 simple_spread"]
    mpe = mpe_rows[0]["steps_per_s"] if mpe_rows else None
    for row in rows:
        row["x_mpe2"] = None if mpe is None else row["steps_per_s"] / mpe
    memory = memory_profile(memory_steps) if memory_steps > 0 and not rendered_only else []
    training_rows: list[dict] = []
    if train_steps > 0 and not rendered_only:
        from training.train.bench import bench_training

        training_rows = bench_training(train_steps)
    return {
        "rendered": bench_rendered(rendered_steps, rounds=rounds) if rendered_steps > 0 else [],
        "steps": steps,
        "rounds": rounds,
        "mpe2_simple_spread_steps_per_s": mpe,
        "mpe2_rounds_steps_per_s": mpe_rows[0]["rounds_steps_per_s"] if mpe_rows else [],
        "configurations": rows,
        "memory_steps": memory_steps,
        "memory_mb": memory,
        "training": training_rows,
        "cpu_count": os.cpu_count(),
    }


def format_bench(result: dict) -> str:
    """The benchmark table."""
    from training.bench_rendered import format_rendered

    if not result["configurations"]:
        return format_rendered(result.get("rendered", []))
    mpe = result["mpe2_simple_spread_steps_per_s"]
    lines = [f"{'environment':<20}{'action mode':<12}{'steps/s':>10}{'x MPE2':>9}", "-" * 51]
    for row in result["configurations"]:
        ratio = "n/a" if row["x_mpe2"] is None else f"{row['x_mpe2']:.2f}"
        lines.append(f"{row['env']:<20}{row['action_mode']:<12}{row['steps_per_s']:>10.0f}{ratio:>9}")
    lines.append(f"{'mpe2 simple_spread':<20}{'N=3':<12}{(mpe or float('nan')):>10.0f}{'1.00' if mpe else 'n/a':>9}")
    if result["memory_mb"]:
        first, last = result["memory_mb"][0], result["memory_mb"][-1]
        peak = max(mb for _, mb in result["memory_mb"])
        lines.append(
            f"\nmemory of top_observer over {result['memory_steps']} steps: {first[1]:.1f} MB at start, "
            f"{last[1]:.1f} MB at the end, peak {peak:.1f} MB"
        )
    lines.append(
        f"({result['steps']} random-action steps per row, best of {result.get('rounds', 1)} interleaved rounds, "
        f"{result['cpu_count']} cores)"
    )
    if result.get("rendered"):
        lines.append("\n" + format_rendered(result["rendered"]))
    if result.get("training"):
        from training.train.bench import format_training

        lines += format_training(result["training"])
    return "\n".join(lines)
