"""Start-up time of the ``moma-env`` command line: ``moma-env bench --cli``.

Each row is the wall time (s) of one command run in a fresh Python process, as the
console script runs it (``from training.cli import main; sys.exit(main())``): the
bare interpreter (``python -c pass``, the floor every row pays), ``moma-env --help``
and every subcommand's ``--help``. The rows are run in interleaved rounds (every row
once per round, so a busy moment of the machine touches every row alike); each row
reports its best and median round. What ``--help`` may import is checked by
``tests/test_cli_light.py`` (no torch, Stable-Baselines3, OpenCV, pymunk, matplotlib).
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from collections.abc import Sequence

__all__ = ["CLI_ROWS", "run_cli_bench", "format_cli_bench"]

#: The commands timed, each followed by ``--help`` (the empty one: ``moma-env --help``).
CLI_ROWS: tuple[tuple[str, ...], ...] = (
    (),
    ("experiment", "square"),
    ("experiment", "line"),
    ("experiment", "flips"),
    ("experiment", "consistency"),
    ("bench",),
    ("evaluate",),
    ("train",),
)
_MAIN = "import sys; from training.cli import main; sys.exit(main(sys.argv[1:]))"


def _time_once(argv: Sequence[str]) -> float:
    start = time.perf_counter()
    subprocess.run(list(argv), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - start


def run_cli_bench(rounds: int = 3, python: str = sys.executable) -> dict:
    """Wall times (s) of the interpreter alone and of every ``--help`` of :data:`CLI_ROWS`
    over ``rounds`` interleaved rounds: ``{"rounds", "python", "rows": [{"command",
    "best_s", "median_s"}]}``."""
    if isinstance(rounds, bool) or not isinstance(rounds, int) or rounds < 1:
        raise ValueError(f"rounds must be an int >= 1, got {rounds!r}")
    commands = {"python -c pass": [python, "-c", "pass"]}
    for row in CLI_ROWS:
        commands[" ".join(("moma-env", *row, "--help"))] = [python, "-c", _MAIN, *row, "--help"]
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(rounds):
        for name, argv in commands.items():
            times[name].append(_time_once(argv))
    rows = [{"command": name, "best_s": min(t), "median_s": statistics.median(t)} for name, t in times.items()]
    return {"rounds": rounds, "python": python, "rows": rows}


def format_cli_bench(result: dict) -> str:
    """The rows as a Markdown table (seconds)."""
    lines = [
        f"moma-env start-up, wall time of a fresh process, best and median of {result['rounds']} rounds",
        "",
        "| command | best (s) | median (s) |",
        "|---|---|---|",
    ]
    lines += [f"| `{row['command']}` | {row['best_s']:.2f} | {row['median_s']:.2f} |" for row in result["rows"]]
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - python -m training.bench_cli [ROUNDS]
    print(format_cli_bench(run_cli_bench(int(sys.argv[1]) if len(sys.argv) > 1 else 3)))
