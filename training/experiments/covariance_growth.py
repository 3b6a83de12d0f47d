"""How MOMA's error grows with the number of switches, predicted and realised.

``python -m training.experiments.covariance_growth [--switches 24] [--runs 50] [--seed 0] [--json]``

The estimator alone (no simulator): two planar UGVs under a downward camera
2 m up, leapfrogging. Every detection's ``T_c_m`` is the truth perturbed by a
Gaussian error of a fixed covariance (camera frame, the convention of
:class:`~moma_env.estimator.detection.Detection`), which the detection carries.
Two teams: one that **travels** (each mover drives 0.5 m along x between its
switches) and one that **stays** (each mover is declared mobile and static again
in place). After switch k the robot that just stopped is frozen from its window;
its predicted position standard deviation (root of the trace of the x, y
covariance) and its realised RMS position error over the runs are recorded.

A team that stays accumulates independent window errors: its error grows as
n^0.5. A team that travels turns every heading error into lateral error along
the rest of the path, so its error grows faster. The command fits the exponent
``a`` of ``std ~ n^a`` over switches 5 to ``switches`` for both, predicted
(the covariance) and realised (Monte Carlo).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator
from moma_env.estimator.uncertainty import apply_error

__all__ = ["SyntheticLeapfrog", "growth", "fit_exponent", "main"]

#: Board mount on a robot (on top, 0.3 m up, facing up) and the downward camera's mount on the UAV.
BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.0, 0.0, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, -0.05])
#: Frame period (s): 25 Hz.
DT = 0.04
#: Standard deviations of a detection's error (m, m, m, rad, rad, rad) in the camera frame.
DETECTION_STD = (0.004, 0.004, 0.01, 0.01, 0.01, 0.004)
#: Distance a travelling mover drives per switch (m).
STEP_M = 0.5
#: Switches before this one are left out of the exponent's fit (the first few are dominated by the initial window).
FIT_FROM = 5


class SyntheticLeapfrog:
    """Two UGVs leapfrogging under a camera whose detections have a known Gaussian error.

    Args:
        seed: seed of the detection noise.
        travel: movers drive ``STEP_M`` along x between their switches (else they stay).
        planar: declare the UGVs upright on the floor to the estimator.
        window: the estimator's switch window.
    """

    names = ("ugv_0", "ugv_1")

    def __init__(self, seed: int, *, travel: bool, planar: bool = True, window: int = 10):
        self.rng = np.random.default_rng(seed)
        self.travel = travel
        self.truth = {"ugv_0": g.se2_to_se3(0.0, 0.0, 0.3), "ugv_1": g.se2_to_se3(0.0, 0.6, 0.3)}
        self.std = np.array(DETECTION_STD)
        self.covariance = np.diag(self.std**2)
        self.estimator = MomaEstimator(EstimatorConfig(window=window, gate=None))
        for i, name in enumerate(self.names):
            self.estimator.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=self.truth[name], planar=planar)
        self.estimator.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
        self.time = 0.0

    def frame(self) -> None:
        """One camera frame: the camera above the pair's midpoint, both boards detected."""
        self.time = round(self.time + DT, 10)
        centre = 0.5 * (self.truth["ugv_0"][:3, 3] + self.truth["ugv_1"][:3, 3])
        T_w_c = g.make_transform(g.rot_z(0.1 * self.time), [centre[0], centre[1], 2.0]) @ CAM_DOWN
        detections = []
        for i, name in enumerate(self.names):
            T_c_m = g.invert(T_w_c) @ self.truth[name] @ BOARD_TOP
            noisy = apply_error(T_c_m, self.rng.normal(0.0, self.std))
            detections.append(Detection("down", i, noisy, np.empty((0, 2)), (), self.time, covariance=self.covariance))
        self.estimator.update(self.time, detections)

    def switch(self, k: int) -> str:
        """Switch ``k``: robot ``k % 2`` moves (or not) and stops; returns its name once it is frozen."""
        mover, other = self.names[k % 2], self.names[(k + 1) % 2]
        while not self.estimator.window_ready(other):
            self.frame()
        self.estimator.set_static(mover, False, self.time)
        if self.travel:
            x, y, yaw = g.se3_to_se2(self.truth[mover])
            self.truth[mover] = g.se2_to_se3(x + STEP_M, y, yaw)
        self.frame()
        self.estimator.set_static(mover, True, self.time)
        while not self.estimator.window_ready(mover):
            self.frame()
        return mover


def fit_exponent(values: Sequence[float]) -> float:
    """``a`` of ``values[k - 1] ~ k^a``, least squares in log-log over k >= ``FIT_FROM``."""
    v = np.asarray(values, dtype=float)
    n = np.arange(1, v.size + 1)
    keep = n >= FIT_FROM
    if keep.sum() < 2:
        raise ValueError(f"need at least {FIT_FROM + 1} values to fit an exponent, got {v.size}")
    return float(np.polyfit(np.log(n[keep]), np.log(v[keep]), 1)[0])


def growth(switches: int, runs: int, seed: int, travel: bool) -> dict:
    """Predicted standard deviation and realised RMS position error (m) after every switch.

    Returns:
        ``{"travel", "predicted_std_m": [per switch], "rms_error_m": [per switch],
        "predicted_exponent", "realised_exponent"}``; the prediction is run ``seed``'s
        (it depends on the geometry only, not on the noise).
    """
    if switches < FIT_FROM + 1 or runs < 1:
        raise ValueError(f"switches must be >= {FIT_FROM + 1} and runs >= 1, got {switches} and {runs}")
    squared = np.zeros(switches)
    predicted = []
    for run in range(runs):
        sim = SyntheticLeapfrog(seed + run, travel=travel)
        for k in range(switches):
            name = sim.switch(k)
            e = sim.estimator.estimate(name)
            squared[k] += float(np.sum((e.T_w_b[:2, 3] - sim.truth[name][:2, 3]) ** 2))
            if run == 0:
                predicted.append(float(np.sqrt(e.covariance[0, 0] + e.covariance[1, 1])))
    rms = np.sqrt(squared / runs)
    return {
        "travel": travel,
        "predicted_std_m": predicted,
        "rms_error_m": rms.tolist(),
        "predicted_exponent": fit_exponent(predicted),
        "realised_exponent": fit_exponent(rms),
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m training.experiments.covariance_growth", description=__doc__.split("\n\n")[0])
    parser.add_argument("--switches", type=int, default=24, help=f"switches per run (default 24, >= {FIT_FROM + 1})")
    parser.add_argument("--runs", type=int, default=50, help="Monte Carlo runs per team (default 50)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first run; run k uses seed+k (default 0)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args(argv)
    if args.switches < FIT_FROM + 1 or args.runs < 1 or args.seed < 0:
        parser.error(f"--switches must be >= {FIT_FROM + 1}, --runs >= 1 and --seed >= 0")
    results = [growth(args.switches, args.runs, args.seed, travel) for travel in (False, True)]
    if args.json:
        print(json.dumps({"switches": args.switches, "runs": args.runs, "seed": args.seed, "teams": results}, indent=2))
        return 0
    print(f"MOMA position error against switches ({args.runs} runs, {args.switches} switches, seed {args.seed}); std ~ n^a fitted from switch {FIT_FROM}")
    print("")
    print(f"| team | predicted std after switch {args.switches} (cm) | realised RMS (cm) | a predicted | a realised |")
    print("|---|---:|---:|---:|---:|")
    for r in results:
        team = "travels 0.5 m per switch" if r["travel"] else "stays in place"
        print(
            f"| {team} | {100 * r['predicted_std_m'][-1]:.2f} | {100 * r['rms_error_m'][-1]:.2f} | "
            f"{r['predicted_exponent']:.2f} | {r['realised_exponent']:.2f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
