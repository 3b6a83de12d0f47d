"""The training benchmark's rows: where a training run's time goes (env, collection, learner)."""

from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")


def test_sb3_row_splits_the_time_into_env_collection_and_learner():
    from training.train.bench import format_training, training_fps

    row = training_fps(512, envs=2, route="shared", scenario="top_observer")
    assert row["timesteps"] >= 512
    # The env's step is part of the collection, and collection plus learning part of the run.
    assert 0.0 < row["env_s"] < row["collect_s"]
    assert row["learn_s"] > 0.0
    assert row["collect_s"] + row["learn_s"] <= row["seconds"]
    env_steps = row["timesteps"] / 2  # two UGV slots per env step on the shared route
    bound = env_steps / (row["collect_s"] - row["env_s"] + row["learn_s"])
    assert row["learner_bound_env_steps_per_s"] == pytest.approx(bound)
    assert row["learner_bound_env_steps_per_s"] > row["env_steps_per_s"]
    table = "\n".join(format_training([row]))
    assert "learner bound" in table and f"{bound:.0f}" in table
    assert f"{100 * row['env_s'] / row['seconds']:.0f}" in table


def test_centralised_row_times_the_env_under_its_wrappers():
    from training.train.bench import training_fps

    row = training_fps(256, envs=1, route="centralised", scenario="top_observer")
    assert 0.0 < row["env_s"] < row["collect_s"]
    assert row["learner_bound_env_steps_per_s"] > row["env_steps_per_s"]


def test_the_env_clock_times_the_vec_env_under_the_wrappers():
    """``training_fps`` times ``venv.unwrapped``'s ``step_wait``: SB3's innermost VecEnv, under
    ``VecNormalize`` and ``VecMonitor``, whose ``step_wait`` is where the copies step."""
    import gymnasium
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    import moma_env  # noqa: F401  (registers the ids)

    inner = DummyVecEnv([lambda: gymnasium.make("moma_env/TopObserver-v0")])
    try:
        assert VecNormalize(VecMonitor(inner)).unwrapped is inner
        assert inner.unwrapped is inner
    finally:
        inner.close()


def test_batch_size_rows_record_their_size_and_ratio_to_the_first():
    from training.train.bench import compare_batch_sizes

    rows = compare_batch_sizes(256, 1, [64, 128], envs=2, scenario="top_observer", n_steps=32)
    assert [r["batch_size"] for r in rows] == [64, 128]
    assert all(r["n_steps"] == 32 and r["round"] == 0 and r["algo"] == "maskable_ppo" for r in rows)
    assert rows[0]["x_first"] == 1.0
    assert rows[1]["x_first"] == pytest.approx(rows[1]["env_steps_per_s"] / rows[0]["env_steps_per_s"])


def test_the_command_line_refuses_bad_batch_sizes():
    from training.train.bench import main

    for bad in ("0,256", "x", ""):
        with pytest.raises(SystemExit):
            main(["--batch-sizes", bad])


def test_the_table_shows_the_minibatch_size_of_rows_that_give_one():
    from training.train.bench import format_training

    row = {"scenario": "top_observer_team4", "algo": "maskable_ppo", "route": "shared", "envs": 32, "subproc": False, "workers": 2,
           "timesteps": 65536, "seconds": 10.0, "timesteps_per_s": 6553.6, "env_steps_per_s": 1638.4, "env_s": 6.0,
           "learner_bound_env_steps_per_s": 5000.0}
    plain = format_training([row])
    assert "batch" not in plain[1]
    lines = format_training([row | {"batch_size": 2048}, row | {"batch_size": 256}])
    assert "batch" in lines[1] and len(lines[2]) == len(plain[2]) + 7
    assert lines[3].split()[5] == "2048" and lines[4].split()[5] == "256"


def test_the_throughput_target_is_judged_per_setting_on_its_best_round():
    from training.train.bench import TARGET_ENV_STEPS_PER_S, target_lines

    rows = [{"setting": "default", "env_steps_per_s": 900.0}, {"setting": "fastest", "env_steps_per_s": 2400.0},
            {"setting": "default", "env_steps_per_s": 1100.0}, {"setting": "fastest", "env_steps_per_s": TARGET_ENV_STEPS_PER_S}]
    default, fastest = target_lines(rows)
    assert default == ("target >= 10000 env steps/s, learner included, default settings: best 1100, median 1000 over 2 rounds: "
                       "11% of it (missed)")
    assert fastest.startswith("target >= 10000 env steps/s, learner included, fastest settings: best 10000")
    assert fastest.endswith("100% of it (met)")


def test_the_throughput_target_times_the_default_and_the_fastest_settings(monkeypatch):
    from training.train import bench
    from training.train.config import TrainConfig

    calls = []
    monkeypatch.setattr(bench, "training_fps", lambda steps, **kw: calls.append((steps, kw)) or {"env_steps_per_s": 1.0})
    rows = bench.throughput_target(4096, 2)
    assert [(r["round"], r["setting"]) for r in rows] == [(0, "default"), (0, "fastest"), (1, "default"), (1, "fastest")]
    default, fastest = calls[0][1], calls[1][1]
    defaults = TrainConfig(scenario="top_observer_team4")
    assert default == {"envs": defaults.envs, "scenario": "top_observer_team4", "algo": defaults.algo}
    assert fastest == {"envs": 32, "scenario": "top_observer_team4", "algo": "maskable_ppo", "workers": 2, "n_steps": 64}
    with pytest.raises(SystemExit):
        bench.main(["--target", "--batch-sizes", "64,128"])
