"""``moma-env train --backend rllib`` on the session's local Ray (2 CPUs): RLlib's own
checkpoint under a manifest, held-out evaluations through the harness, ``--resume``
from the last checkpoint, and ``moma-env evaluate --policy DIR`` loading the checkpoint
and reproducing the run's last evaluation."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("ray.rllib", reason="needs the 'ray' extra")

from ray_session import ray_local  # noqa: E402,F401

# make test (pytest-xdist, --dist loadgroup) runs every test of the session's Ray on one worker: one Ray.
pytestmark = pytest.mark.xdist_group("ray")

from agents.rllib_policy import RllibPolicy, is_rllib_run  # noqa: E402
from training.cli import main  # noqa: E402
from training.evaluation.harness import evaluate  # noqa: E402
from training.train.evaluation import headline  # noqa: E402

ARGS = ["train", "--backend", "rllib", "--scenario", "top_observer", "--num-envs", "2", "--n-steps", "32", "--batch-size", "64",
        "--max-cycles", "40", "--checkpoint-every", "64", "--eval-every", "64", "--eval-episodes", "2", "--eval-sample-actions", "--seed", "3"]


def test_train_checkpoint_resume_and_evaluate(ray_local, tmp_path, capsys):
    out = tmp_path / "run"
    assert main([*ARGS, "--timesteps", "64", "--out", str(out), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["backend"] == "rllib" and first["num_timesteps"] >= 64 and is_rllib_run(out)
    assert (out / first["checkpoint"] / "rllib_checkpoint.json").is_file()

    assert main([*ARGS, "--timesteps", "64", "--out", str(out)]) == 2  # one run per folder
    assert "already holds a training run" in capsys.readouterr().err
    assert main([*ARGS[:-1], "4", "--timesteps", "256", "--out", str(out), "--resume"]) == 2  # another seed
    assert "seed" in capsys.readouterr().err

    assert main([*ARGS, "--timesteps", "160", "--out", str(out), "--resume", "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert resumed["num_timesteps"] >= 160 and resumed["iteration"] > first["iteration"]
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("checkpoint_")) == [resumed["checkpoint"]]
    records = json.loads((out / "evaluations.json").read_text())["records"]
    assert records[0]["num_timesteps"] == first["num_timesteps"] and records[-1]["num_timesteps"] == resumed["num_timesteps"]

    # the reloaded checkpoint is the policy the run evaluated last: the same sampled held-out episodes, the same numbers
    policy = RllibPolicy.from_dir(out, "top_observer", deterministic=False)  # sampled, as the run evaluated
    result = evaluate("top_observer", policy, 2, 10_000, random_scenarios=True, action_mode="switching", observer_agent=False)
    again = headline(result.summary)
    last = records[-1]
    for key in ("success_rate", "n_switches", "n_refused", "total_reward", "me_m", "e_f_m"):
        assert again[key] == pytest.approx(last[key], nan_ok=True), key

    assert main(["evaluate", "--scenario", "top_observer", "--policy", str(out), "--episodes", "2", "--max-cycles", "20",
                 "--out", str(tmp_path / "eval"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_episodes"] == 2
    assert main(["evaluate", "--scenario", "caterpillar", "--policy", str(out), "--episodes", "1", "--out", str(tmp_path / "e2")]) == 2
    assert "trained on 'top_observer'" in capsys.readouterr().err
