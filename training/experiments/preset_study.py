"""How the ``paper`` preset was chosen: the square under each step of its derivation.

Each candidate changes one physically motivated thing on the way from the
experiments' defaults to :data:`training.experiments.presets.PAPER` (the clean
rendered image; the full 6-DoF estimate of the authors' system; the analogue PAL
video link; the flying altitude; the authors' calibrated lens instead of a
generic f = 420 px one; the lab floor's grain instead of a perfectly plain
floor). The candidates derive from the preset itself, so the study and the
preset cannot drift apart.

    python -m training.experiments.preset_study [--runs 3] [--seed 0] [--jobs 1] [--out runs/preset_study]

prints MOMA's and VO's square statistics per candidate beside the paper's and
writes them to ``OUT/summary.json`` (whole or not at all).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from moma_env.camera import CameraConfig, RenderConfig
from moma_env.io import write_json
from training.experiments.leapfrog_run import summarise
from training.experiments.presets import PAPER, ExperimentPreset
from training.experiments.report_common import cm, pct
from training.experiments.runner import run_many
from training.experiments.square import SquareConfig
from training.experiments.square_report import PAPER_SQUARE

__all__ = ["CANDIDATES", "GENERIC_PAL_CAMERA", "candidate_config", "main"]

#: The lens the preset used before the authors' calibration: a 2.8 mm FPV lens on a
#: 1/3" CCD (81 deg horizontal field of view, f = 420 px at 720 px), square pixels,
#: centred, mild barrel distortion.
GENERIC_PAL_CAMERA = CameraConfig(width=720, height=576, fx=420.0, dist=(-0.05, 0.01, 0.0, 0.0, 0.0), noise_px=0.5)

#: The derivation, in order: name -> the preset tried.
CANDIDATES: dict[str, ExperimentPreset] = {
    "geometric 0.5 px, 2.5 m, 6-DoF": dataclasses.replace(PAPER, camera_backend="geometric"),
    "rendered clean image, 2.5 m, 6-DoF": dataclasses.replace(PAPER, render=RenderConfig()),
    "rendered PAL link, 2.0 m, planar": dataclasses.replace(PAPER, altitude=2.0, planar_ugvs=True),
    "rendered PAL link, 2.0 m, 6-DoF": dataclasses.replace(PAPER, altitude=2.0),
    "generic lens f=420 px, 2.5 m, 6-DoF": dataclasses.replace(PAPER, camera=GENERIC_PAL_CAMERA),
    "perfectly plain floor, 2.5 m, 6-DoF": dataclasses.replace(PAPER, floor_grain=None),
    "rendered PAL link, 2.5 m, 6-DoF (paper)": PAPER,
}


def candidate_config(name: str) -> SquareConfig:
    """The square under candidate ``name`` (KeyError naming the known ones otherwise)."""
    if name not in CANDIDATES:
        raise KeyError(f"unknown candidate {name!r}; known: {list(CANDIDATES)}")
    return CANDIDATES[name].apply(SquareConfig())


def _row(name: str, summary: dict) -> str:
    m, vo = summary["moma"], summary.get("vo")
    vo_text = f"{cm(vo['mean_final_error'], 8)}{100 * vo['track_loss_rate']:>6.0f}%" if vo else f"{'':>8}{'':>7}"
    return (
        f"{name:<42}{cm(m['mean_final_error'], 8)}{cm(m['std_final_error'], 7)}{cm(m['mean_mean_error'], 8)}"
        f"{pct(m['mean_final_error_pct_path'], 9)}{vo_text}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run every candidate (or those named with ``--only``) and print the comparison."""
    parser = argparse.ArgumentParser(prog="python -m training.experiments.preset_study", description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per candidate (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first run (default 0)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--only", nargs="+", choices=list(CANDIDATES), default=None, help="run only these candidates")
    parser.add_argument("--out", type=Path, default=Path("runs/preset_study"), help="output folder (default runs/preset_study)")
    args = parser.parse_args(argv)
    if args.runs < 1 or args.jobs < 1 or args.seed < 0:
        parser.error("--runs and --jobs must be >= 1 and --seed >= 0")
    names = args.only or list(CANDIDATES)
    head = f"{'candidate (square, quadcopter)':<42}{'ME_f cm':>8}{'std':>7}{'ME cm':>8}{'% path':>9}{'VO E_f':>8}{'lost':>7}"
    lines = [head, "-" * len(head)]
    results = {}
    start = time.perf_counter()
    for name in names:
        runs = run_many(candidate_config(name), args.runs, args.seed, log=lambda line, n=name: print(f"[{n}] {line}", file=sys.stderr), jobs=args.jobs)
        results[name] = summarise(runs)
        lines.append(_row(name, results[name]))
    p = PAPER_SQUARE["moma"]
    lines.append(f"{'MOMA (paper, real robots)':<42}{p['ME_f_cm']:>8.2f}{p['ME_f_std_cm']:>7.2f}{p['ME_cm']:>8.2f}{p['pct_path']:>9.3f}")
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "summary.json", {"runs": args.runs, "seed": args.seed, "candidates": results, "paper": PAPER_SQUARE})
    print("\n".join(lines) + f"\n\nsummary: {args.out / 'summary.json'}\nwall time: {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
