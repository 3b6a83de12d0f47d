"""Env-steps per second of the batched env (:mod:`moma_env.vector`) against MPE2 and VMAS.

``moma-env bench --vector`` (or ``python -m training.bench_vector``) times, in
interleaved rounds of one run:

* the batched MOMA env (``moma_env.vector.make``, geometric camera, random actions
  drawn before the clock starts) at each ``num_envs`` of ``--num-envs``, for
  ``top_observer`` (2 UGVs) in switching and velocity mode, ``caterpillar_multi``
  and ``top_observer`` with 8 UGVs (switching);
* with ``--workers W``, ``top_observer`` switching split over ``W`` worker processes
  (``moma_env.vector.make(..., workers=W)``) at each ``num_envs`` >= ``W``;
* ``top_observer`` switching as the PettingZoo env itself (``parallel_env``, one copy,
  timed as MPE2 is: :func:`training.bench_common.steps_per_second`), the row of the
  one-copy target;
* MPE2 ``simple_spread`` (N=3, one env, parallel API, random actions), the
  single-env reference;
* VMAS ``navigation`` (its default agents, CPU, one torch thread) at the same
  ``num_envs``, the vectorised reference (when ``vmas`` is installed);

and prints each rate's best and median over the rounds, its ratio to MPE2's rate
of the same round (best and median), and the breakdown of one MOMA batch step by
stage (each phase of the copies' steps, the cameras' measurement, the garbage collector,
the rest) at the largest ``num_envs``,
and each target of :data:`TARGET_BATCH`, :data:`TARGET_ONE_COPY` and :data:`TARGET_UGV_COST`
met or missed (:func:`target_lines`). An
env-step is one step of one copy. ``--memory-steps N`` then prints the resident
memory over ``N`` env-steps of ``top_observer`` at the largest ``num_envs``, after a
warm-up episode (start, three points between, end), in a fresh process, and whether
it stayed flat (:func:`memory_lines`). A measurement, not an assertion.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = [
    "CASES",
    "ONE_COPY_ROW",
    "moma_rate",
    "vmas_rate",
    "stage_breakdown",
    "run_vector_bench",
    "format_vector_bench",
    "target_lines",
    "vector_memory",
    "memory_run",
    "memory_lines",
    "MEMORY_FLAT_FRACTION",
    "main",
]

#: The MOMA rows: label -> (configuration, options).
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "top_observer switching": ("top_observer", {"action_mode": "switching"}),
    "top_observer velocity": ("top_observer", {"action_mode": "velocity"}),
    "caterpillar_multi switching": ("caterpillar_multi", {"action_mode": "switching"}),
    "top_observer 8 UGVs switching": ("top_observer", {"action_mode": "switching", "n_ugvs": 8}),
}


def _random_batches(envs, count: int, seed: int) -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [envs.sample_actions(rng) for _ in range(count)]


def moma_rate(envs, batches: Sequence[dict[str, np.ndarray]], min_env_steps: int) -> float:
    """Env-steps per second of ``envs`` (a reset :class:`~moma_env.vector.MomaVectorEnv`) stepped
    with ``batches`` in turn until at least ``min_env_steps`` env-steps (and one batch step)."""
    n = max(1, -(-min_env_steps // envs.num_envs))
    start = time.perf_counter()
    for i in range(n):
        envs.step(batches[i % len(batches)])
    return n * envs.num_envs / (time.perf_counter() - start)


def vmas_factory(num_envs: int, seed: int = 0) -> Callable[[int], float] | None:
    """A timer ``f(min_env_steps) -> env-steps/s`` of VMAS ``navigation`` on CPU, or None without vmas."""
    try:
        import torch
        from vmas import make_env
    except ImportError:
        return None
    torch.set_num_threads(1)
    env = make_env(scenario="navigation", num_envs=num_envs, device="cpu", continuous_actions=True, seed=seed)
    env.reset()
    generator = torch.Generator().manual_seed(seed)
    pool = [
        [torch.rand(num_envs, agent.action_size, generator=generator) * 2.0 - 1.0 for agent in env.agents] for _ in range(20)
    ]

    def rate(min_env_steps: int) -> float:
        n = max(1, -(-min_env_steps // num_envs))
        start = time.perf_counter()
        for i in range(n):
            env.step(pool[i % len(pool)])
        return n * num_envs / (time.perf_counter() - start)

    return rate


def vmas_rate(num_envs: int, min_env_steps: int, seed: int = 0) -> float | None:
    """Env-steps per second of VMAS ``navigation`` at ``num_envs`` (None without vmas)."""
    timer = vmas_factory(num_envs, seed)
    return None if timer is None else timer(min_env_steps)


def stage_breakdown(envs, batches: Sequence[dict[str, np.ndarray]], batch_steps: int) -> dict[str, float]:
    """Mean milliseconds of one batch step and of its stages: each phase of the copies'
    steps (:data:`~moma_env.env.parallel.STEP_PHASES`, every copy's: ``physics`` the
    world's control steps, ``localiser`` the estimator's updates, ...) and the cameras'
    batch measurement (:data:`~moma_env.env.parallel.MEASUREMENT`), from the batch's
    ``phase_seconds``; ``gc`` (Python's cyclic garbage collector, wherever it ran:
    :mod:`moma_env.vector.collection` runs it at the end of a batch step, after the
    phases); and ``rest`` (what a batch step does outside them: checking the actions,
    stacking the copies' outputs, the autoresets)."""
    import gc

    from moma_env.env.parallel import MEASUREMENT, STEP_PHASES

    seconds: dict[str, float] = {}
    collecting: list[float] = []
    collected = [0.0]

    def collector(phase: str, info: dict) -> None:
        if phase == "start":
            collecting.append(time.perf_counter())
        elif collecting:
            collected[0] += time.perf_counter() - collecting.pop()

    envs.phase_seconds = seconds
    gc.callbacks.append(collector)
    try:
        start = time.perf_counter()
        for i in range(batch_steps):
            envs.step(batches[i % len(batches)])
        elapsed = time.perf_counter() - start
    finally:
        gc.callbacks.remove(collector)
        envs.phase_seconds = None
    out = {"batch step": elapsed / batch_steps * 1e3}
    for key in (*STEP_PHASES[:5], MEASUREMENT, *STEP_PHASES[5:]):
        out[key] = seconds.get(key, 0.0) / batch_steps * 1e3
    out["gc"] = collected[0] / batch_steps * 1e3
    out["rest"] = out["batch step"] - sum(value for key, value in out.items() if key != "batch step")
    return out


#: The row split over worker processes (``--workers``).
SHARDED_CASE = "top_observer switching"
#: The row of the one-copy target: the PettingZoo env of :data:`SHARDED_CASE` itself.
ONE_COPY_ROW = f"{SHARDED_CASE}, PettingZoo env"


def run_vector_bench(
    num_envs: Sequence[int], rounds: int = 3, min_env_steps: int = 2000, seed: int = 0, workers: Sequence[int] = ()
) -> dict:
    """Every row in ``rounds`` interleaved rounds (see the module docstring); ``workers``: the
    worker counts (each >= 2) of the sharded rows."""
    from moma_env import vector
    from moma_env.env.factory import parallel_env
    from training.bench_common import mpe2_reference, steps_per_second

    if rounds < 1 or min_env_steps < 1 or not num_envs or min(num_envs) < 1:
        raise ValueError(f"need rounds >= 1, min_env_steps >= 1 and num_envs >= 1, got {rounds}, {min_env_steps}, {list(num_envs)}")
    if any(w < 2 for w in workers):
        raise ValueError(f"need workers >= 2 (one worker is the in-process row's work plus a pipe), got {list(workers)}")
    make_mpe2 = mpe2_reference()
    one_name, one_options = CASES[SHARDED_CASE]

    def make_one_copy():
        return parallel_env(one_name, **one_options)

    moma: dict[tuple[str, int], Any] = {}
    for label, (name, options) in CASES.items():
        for n in num_envs:
            envs = vector.make(name, n, **options)
            envs.reset(seed=seed)
            moma[(label, n)] = (envs, _random_batches(envs, 16, seed))
    name, options = CASES[SHARDED_CASE]
    for w in workers:
        for n in num_envs:
            if n >= w:
                envs = vector.make(name, n, workers=w, **options)
                envs.reset(seed=seed)
                moma[(f"{SHARDED_CASE}, {w} workers", n)] = (envs, _random_batches(envs, 16, seed))
    vmas = {n: vmas_factory(n, seed) for n in num_envs}
    rates: dict[str, list[float]] = {}
    ratios: dict[str, list[float]] = {}
    for _ in range(rounds):
        mpe2 = steps_per_second(make_mpe2, min_env_steps, seed=seed) if make_mpe2 is not None else None
        rates.setdefault("mpe2 simple_spread N=3 (one env)", []).append(mpe2 if mpe2 is not None else float("nan"))
        rows: dict[str, float] = {ONE_COPY_ROW: steps_per_second(make_one_copy, min_env_steps, seed=seed)}
        for (label, n), (envs, batches) in moma.items():
            rows[f"{label}, num_envs={n}"] = moma_rate(envs, batches, min_env_steps)
        for n, timer in vmas.items():
            if timer is not None:
                rows[f"vmas navigation, num_envs={n}"] = timer(min_env_steps)
        for key, value in rows.items():
            rates.setdefault(key, []).append(value)
            if mpe2:
                ratios.setdefault(key, []).append(value / mpe2)
    largest = max(num_envs)
    envs, batches = moma[("top_observer switching", largest)]
    breakdown = stage_breakdown(envs, batches, max(2, -(-min_env_steps // largest)))
    for envs, _ in moma.values():
        envs.close()
    return {
        "rounds": rounds,
        "min_env_steps": min_env_steps,
        "num_envs": list(num_envs),
        "rates": rates,
        "ratios": ratios,
        "breakdown_num_envs": largest,
        "breakdown_ms": breakdown,
    }


def vector_memory(num_envs: int, env_steps: int, samples: int = 3, seed: int = 0) -> list[tuple[int, float]]:
    """Resident memory (MB) of a batch of ``num_envs`` top_observer copies (switching mode,
    random actions, autoresets included) over ``env_steps`` env-steps after one warm-up
    episode: ``(env-steps done, RSS)`` at the start and at ``samples - 1`` even points after."""
    from moma_env import vector
    from training.bench_common import resident_mb

    if num_envs < 1 or env_steps < num_envs or samples < 2:
        raise ValueError(f"need num_envs >= 1, env_steps >= num_envs and samples >= 2, got {num_envs}, {env_steps}, {samples}")
    envs = vector.make("top_observer", num_envs, max_cycles=200)
    envs.reset(seed=seed)
    batches = _random_batches(envs, 16, seed)
    for i in range(200):  # one whole episode of every copy: the warm-up
        envs.step(batches[i % len(batches)])
    total = env_steps // num_envs
    marks = {round(total * k / (samples - 1)) for k in range(1, samples)}
    out = [(0, resident_mb())]
    for i in range(1, total + 1):
        envs.step(batches[i % len(batches)])
        if i in marks:
            out.append((i * num_envs, resident_mb()))
    envs.close()
    return out


def memory_run(num_envs: int, env_steps: int, samples: int = 5, seed: int = 0) -> dict:
    """:func:`vector_memory` in a fresh process (so that its RSS is the batch's alone, not
    what the table's runs left in this process's heap), as the benchmark's result records
    it: ``{"num_envs", "env_steps", "rss_mb": [[env-steps done, RSS (MB)], ...]}``."""
    from training.bench_common import in_fresh_process

    rss = in_fresh_process(vector_memory, num_envs, env_steps, samples, seed)
    return {"num_envs": num_envs, "env_steps": env_steps, "rss_mb": [[done, mb] for done, mb in rss]}


#: Memory counts as flat when the RSS at the end is within this fraction of the RSS at the
#: first sample after the start: a leak of 100 bytes an env-step over the last 750,000
#: env-steps of 10^6 at 1,024 copies (75 MB on about 1 GB) fails it, the sawtooth of the
#: retired physics spaces' collection (within 30 MB, docs/vector.md) does not.
MEMORY_FLAT_FRACTION = 0.05


def memory_lines(memory: dict) -> list[str]:
    """The memory run of :func:`memory_run` as lines: every sample, then whether the RSS
    stayed flat after the first sample past the start (:data:`MEMORY_FLAT_FRACTION`)."""
    rss = memory["rss_mb"]
    n = memory["num_envs"]
    lines = [f"memory, top_observer switching, num_envs={n}, after a warm-up episode of every copy:"]
    lines += [f"  after {done:>9} env-steps  RSS {mb:8.1f} MB" for done, mb in rss]
    (first_done, first), (last_done, last) = rss[1], rss[-1]
    change = (last - first) / first
    lines.append(
        f"target: memory flat over {memory['env_steps']} env-steps at num_envs={n}: RSS {first:.1f} MB after {first_done} "
        f"env-steps, {last:.1f} MB after {last_done} ({change:+.1%}; flat: within {MEMORY_FLAT_FRACTION:.0%}) "
        f"({'met' if abs(change) <= MEMORY_FLAT_FRACTION else 'missed'})"
    )
    return lines


#: What the batched env is built towards, as ratios to MPE2's single-env rate of the same
#: round (docs/vector.md, "Speed"): at least this many times MPE2 with this many copies...
TARGET_BATCH = (1024, 15.0)
#: ... and for one copy (the PettingZoo env).
TARGET_ONE_COPY = 2.5
#: Added UGVs cost no worse than linearly: 8 UGVs take at most 4 times the time of 2.
TARGET_UGV_COST = (2, 8)


def target_lines(result: dict) -> list[str]:
    """Each target met or missed by :func:`run_vector_bench`'s ``result`` (best ratio over the
    rounds; the rows a run did not time, and the MPE2 ratios of a run without MPE2, are left out)."""
    ratios, rates = result["ratios"], result["rates"]
    lines = []

    def verdict(value: float, goal: float) -> str:
        return "met" if value >= goal else "missed"

    n, factor = TARGET_BATCH
    for key in [k for k in ratios if k.startswith(SHARDED_CASE) and k.endswith(f"num_envs={n}")]:
        best = max(ratios[key])
        lines.append(f"target >= {factor:g}x MPE2 at num_envs={n}: {key}: {best:.2f}x ({verdict(best, factor)})")
    key = ONE_COPY_ROW if ONE_COPY_ROW in ratios else f"{SHARDED_CASE}, num_envs=1"  # the latter: results from before the row
    if key in ratios:
        best = max(ratios[key])
        lines.append(f"target >= {TARGET_ONE_COPY:g}x MPE2 for one copy: {key}: {best:.2f}x ({verdict(best, TARGET_ONE_COPY)})")
    few, many = TARGET_UGV_COST
    largest = max(result["num_envs"])
    few_key, many_key = f"top_observer switching, num_envs={largest}", f"top_observer {many} UGVs switching, num_envs={largest}"
    if few_key in rates and many_key in rates:
        cost = max(rates[few_key]) / max(rates[many_key])
        limit = many / few
        lines.append(
            f"target: {many} UGVs cost at most {limit:g}x the time of {few} (linear), num_envs={largest}: "
            f"{cost:.2f}x ({'met' if cost <= limit else 'missed'})"
        )
    return lines


def format_vector_bench(result: dict) -> str:
    """The table of :func:`run_vector_bench`'s result."""
    lines = [f"{'row':<52}{'best/s':>10}{'median/s':>10}{'x MPE2 best':>13}{'median':>8}", "-" * 93]
    for key, values in result["rates"].items():
        ratio = result["ratios"].get(key)
        extra = f"{max(ratio):>13.2f}{statistics.median(ratio):>8.2f}" if ratio else ""
        lines.append(f"{key:<52}{max(values):>10.0f}{statistics.median(values):>10.0f}{extra}")
    lines.append(
        f"(env-steps per second, {result['rounds']} interleaved rounds of at least {result['min_env_steps']} env-steps per row; "
        "x MPE2: the rate over MPE2's in the same round)"
    )
    lines.append(f"one batch step of top_observer switching at num_envs={result['breakdown_num_envs']}:")
    breakdown = result["breakdown_ms"]
    for key, value in breakdown.items():
        lines.append(f"  {key:<20}{value:9.2f} ms")
    stages = {k: v for k, v in breakdown.items() if k != "batch step"}
    bound = max(stages, key=stages.get)
    lines.append(
        f"the batch step is bounded by {bound!r}: {stages[bound] / breakdown['batch step']:.0%} of it; "
        f"the step costs {breakdown['batch step'] / stages[bound]:.2f}x that stage alone"
    )
    lines.extend(target_lines(result))
    if "memory" in result:
        lines.extend(memory_lines(result["memory"]))
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Env-steps per second of the batched env against MPE2 and VMAS.")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[1, 64, 256, 1024], help="batch sizes (default 1 64 256 1024)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument(
        "--workers", type=int, nargs="*", default=[2],
        help="worker counts of the sharded top_observer rows (default 2; --workers alone: none)",
    )
    parser.add_argument("--min-env-steps", type=int, default=2000, help="env-steps per row and round (default 2000)")
    parser.add_argument(
        "--memory-steps", type=int, default=0,
        help="then: RSS over this many env-steps of top_observer at the largest --num-envs (e.g. 1000000; default 0: off)",
    )
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.min_env_steps < 1 or min(args.num_envs) < 1 or args.memory_steps < 0:
        parser.error("--rounds, --min-env-steps and --num-envs must be >= 1, --memory-steps >= 0")
    if any(w < 2 for w in args.workers):
        parser.error("--workers must be >= 2")
    if 0 < args.memory_steps < max(args.num_envs):
        parser.error(f"--memory-steps must be 0 or at least the largest --num-envs ({max(args.num_envs)})")
    result = run_vector_bench(args.num_envs, args.rounds, args.min_env_steps, workers=args.workers)
    if args.memory_steps:
        result["memory"] = memory_run(max(args.num_envs), args.memory_steps)
    print(format_vector_bench(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
