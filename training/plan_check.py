"""How often the MOMA navigation planner finds a valid plan on random scenarios.

``python -m training.plan_check [--seeds N]`` plans every configuration's random
scenarios for seeds 0..N-1 and prints, per configuration, how many plans were
found, how many of those ``validate`` accepts, and how many scenarios had
obstacles. A plan that fails validation is counted, never hidden.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from moma_env.planning import PlanningError, plan, validate
from moma_env.scenarios import CONFIGURATIONS

__all__ = ["plan_success", "main"]


def plan_success(configuration: str, seeds: int) -> dict[str, int]:
    """Counts of found, valid and obstacle-bearing random scenarios over ``seeds`` seeds."""
    cls = CONFIGURATIONS[configuration]
    found = valid = with_obstacles = 0
    for seed in range(seeds):
        config = cls.random(np.random.default_rng(seed))
        scenario = config.scenario()
        with_obstacles += bool(scenario.world.arena.obstacles)
        try:
            result = plan(scenario)
        except PlanningError:
            continue
        found += 1
        valid += not validate(scenario, result)
    return {"seeds": seeds, "found": found, "valid": valid, "with_obstacles": with_obstacles}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m training.plan_check", description=__doc__)
    parser.add_argument("--seeds", type=int, default=100, help="random seeds per configuration (default 100)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    print(f"{'configuration':<20}{'found':>8}{'valid':>8}{'obstacles':>11}  (of {args.seeds} random seeds)")
    for name in CONFIGURATIONS:
        r = plan_success(name, args.seeds)
        print(f"{name:<20}{r['found']:>8}{r['valid']:>8}{r['with_obstacles']:>11}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
