"""The README's comparison table from ``moma-env evaluate`` output folders.

``python -m training.train.compare runs/evaluate/top_observer_scripted runs/evaluate/top_observer_random ...``
reads each folder's ``summary.json`` and prints one markdown row per policy:
success, time to goal (s, mean ± std over successful episodes), switches and
refused requests per episode, ME_f and ME (cm, mean over robots of the means
over episodes; :func:`training.train.evaluation.headline`). Rows of
different scenarios or first seeds are refused: the table compares policies on
the same held-out episodes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path


__all__ = ["comparison_table", "main"]


def _number(value: float, scale: float = 1.0, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(value) else f"{scale * value:.{digits}f}"


def comparison_table(summaries: Sequence[dict]) -> str:
    """Markdown table of ``summary.json`` contents (see the module docstring)."""
    from training.train.evaluation import headline

    keys = {(s["scenario"], s["seed"], s["n_episodes"], s["random_scenarios"]) for s in summaries}
    if len(keys) != 1:
        raise ValueError(f"the evaluations differ in scenario, first seed, episodes or layouts: {sorted(keys)}")
    lines = ["| policy | success | time to goal s | switches | refused | ME_f cm | ME cm |", "|---|---|---|---|---|---|---|"]
    for s in summaries:
        h = headline(s["summary"])
        ttg = _number(h["time_to_goal_s"], digits=1)
        if math.isfinite(h["time_to_goal_std_s"]):
            ttg += f" ± {h['time_to_goal_std_s']:.1f}"
        lines.append(
            f"| {s['policy']} | {100 * h['success_rate']:.0f} % | {ttg} | {_number(h['n_switches'], digits=1)} | "
            f"{_number(h['n_refused'], digits=1)} | {_number(h['e_f_m'], 100)} | {_number(h['me_m'], 100)} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m training.train.compare", description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="output folders of moma-env evaluate (each with summary.json)")
    args = parser.parse_args(argv)
    summaries = []
    for folder in args.folders:
        path = folder / "summary.json"
        if not path.is_file():
            print(f"compare: {str(folder)!r} holds no summary.json", file=sys.stderr)
            return 2
        summaries.append(json.loads(path.read_text(encoding="utf-8")))
    try:
        print(comparison_table(summaries))
    except ValueError as err:
        print(f"compare: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
