"""Training is deterministic for a given seed and torch thread count (docs/training.md, "Determinism").

Two runs of the same small configuration write bit-identical model parameters (the
policy's state dict stored in the model zip, compared tensor by tensor) and the same
held-out evaluation numbers; another seed trains other weights. Runs are a few
thousand timesteps of tiny networks: determinism, not learning.
"""

from __future__ import annotations

import json

import pytest
import torch
from stable_baselines3.common.save_util import load_from_zip_file

from agents.learned import read_manifest
from training.train.config import TrainConfig
from training.train.run import train

#: Record keys that measure the machine, not the run (seconds of wall time).
TIMING_KEYS = frozenset({"wall_time_s", "eval_seconds"})

CASES = {
    "maskable_ppo_team4_shared": dict(scenario="top_observer_team4", algo="maskable_ppo", route="shared", steps=2048, n_steps=64),
    "ppo_top_observer_shared": dict(scenario="top_observer", algo="ppo", route="shared", steps=2048, n_steps=64),
}


def small(**changes) -> TrainConfig:
    base = dict(
        envs=2, batch_size=64, net_arch=(16,), max_cycles=60, checkpoint_every=10**6,
        eval_every=1024, eval_episodes=1, eval_max_cycles=40, torch_threads=1,
    )
    return TrainConfig(**(base | changes))


def _saved_run(out) -> tuple[dict[str, torch.Tensor], list[dict]]:
    """The policy's state dict from the run's final model zip, and its evaluation records without timings."""
    manifest = read_manifest(out)
    _, params, _ = load_from_zip_file(out / manifest["model"], device="cpu")
    records = json.loads((out / "evaluations.json").read_text())["records"]
    return params["policy"], [{k: v for k, v in r.items() if k not in TIMING_KEYS} for r in records]


def _same_weights(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_same_seed_trains_the_same_weights_and_evaluations(tmp_path, case):
    config = small(**CASES[case])
    train(config, tmp_path / "a")
    train(config, tmp_path / "b")
    weights_a, records_a = _saved_run(tmp_path / "a")
    weights_b, records_b = _saved_run(tmp_path / "b")
    assert len(weights_a) > 0 and _same_weights(weights_a, weights_b)
    assert [r["num_timesteps"] for r in records_a] == [1024, 2048]
    assert records_a == records_b  # every number of every held-out evaluation, NaN (null) included
    train(small(**CASES[case], seed=1), tmp_path / "c")
    weights_c, _ = _saved_run(tmp_path / "c")
    assert not _same_weights(weights_a, weights_c)  # the seed matters: the comparison above can fail
