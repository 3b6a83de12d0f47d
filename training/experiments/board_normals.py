"""How far off the detected board normals are in the environments: ``moma-env experiment flips --env-episodes``.

The flip experiment (:mod:`training.experiments.flip_rate`) measures one board at
3 m; this one measures every detection the environments make while their
scripted baseline drives them (random layouts, the default geometric camera and
pose rule): for each detection, the angle between the detected board normal
(third column of ``R_c_m``) and the true one, from the world's true camera and
board poses. A flipped pose shows as an angle of about twice the viewing angle;
a pose of a board seen face-on (the caterpillars' forward cameras) cannot be
told from its mirror image, so this reports the angles themselves rather than a
flip count.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["normal_errors", "format_normal_table"]


def normal_errors(configuration: str, episodes: int, seed: int = 0) -> dict:
    """Statistics of the detected normals' angular errors (deg) in ``configuration``.

    Runs ``episodes`` episodes of the configuration's scripted baseline on random
    layouts (episode k seeded ``seed + k``).

    Returns:
        ``{"configuration", "episodes", "seed", "detections", "median_deg",
        "p99_deg", "max_deg", "over_5_deg"}`` (``over_5_deg``: fraction of detections
        whose normal is more than 5 degrees off).
    """
    from agents.policies import scripted_policy
    from moma_env.env.factory import parallel_env
    from moma_env.geometry import invert

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    env = parallel_env(configuration, random_scenarios=True)
    policy = scripted_policy(configuration)
    angles: list[float] = []
    for k in range(episodes):
        observations, infos = env.reset(seed=seed + k)
        core = env.unwrapped
        policy.reset(core, seed=seed + k)
        while env.agents:
            observations, _, _, _, infos = env.step(policy.act(observations, infos))
            for d in core.detections:
                T_c_m = invert(core.world.camera_transform(d.camera_id)) @ core.world.board_transform(core.board_device(d.board_id))
                cosine = float(np.clip(T_c_m[:3, 2] @ d.T_c_m[:3, 2], -1.0, 1.0))
                angles.append(math.degrees(math.acos(cosine)))
    values = np.array(angles)
    empty = values.size == 0
    return {
        "configuration": configuration,
        "episodes": episodes,
        "seed": seed,
        "detections": int(values.size),
        "median_deg": math.nan if empty else float(np.median(values)),
        "p99_deg": math.nan if empty else float(np.percentile(values, 99)),
        "max_deg": math.nan if empty else float(values.max()),
        "over_5_deg": math.nan if empty else float(np.mean(values > 5.0)),
    }


def format_normal_table(results: Sequence[dict]) -> str:
    """The results of :func:`normal_errors` as a Markdown table."""
    head = "| configuration | detections | median deg | 99th percentile deg | max deg | over 5 deg |"
    rule = "|---|---:|---:|---:|---:|---:|"
    rows = [
        f"| {r['configuration']} | {r['detections']} | {r['median_deg']:.2f} | {r['p99_deg']:.2f} | {r['max_deg']:.2f} | "
        f"{100.0 * r['over_5_deg']:.2f} % |"
        for r in results
    ]
    title = (
        f"Angle between detected and true board normals, scripted baseline, {results[0]['episodes']} random layouts "
        f"per configuration (seed {results[0]['seed']})"
    )
    return "\n".join([title, "", head, rule, *rows])
