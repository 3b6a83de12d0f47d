"""The vector benchmark (training.bench_vector): what it reports, not how fast anything is."""

import pytest

from moma_env.env.parallel import MEASUREMENT, STEP_PHASES
import json

import training.bench_vector as bench_vector
from training.bench_vector import (
    CASES, MEMORY_FLAT_FRACTION, ONE_COPY_ROW, format_vector_bench, memory_lines, run_vector_bench, target_lines, vector_memory,
)
from training.cli import main


def test_the_vector_bench_reports_every_row_and_stage():
    result = run_vector_bench([1, 3], rounds=2, min_env_steps=6, workers=[2])
    for label in CASES:
        for n in (1, 3):
            rates = result["rates"][f"{label}, num_envs={n}"]
            assert len(rates) == 2 and all(r > 0 for r in rates)
    # the sharded row only where there is a copy per worker
    assert len(result["rates"]["top_observer switching, 2 workers, num_envs=3"]) == 2
    assert not any(key.endswith("2 workers, num_envs=1") for key in result["rates"])
    # the PettingZoo env itself, the one-copy target's row, in every round
    assert len(result["rates"][ONE_COPY_ROW]) == 2 and all(r > 0 for r in result["rates"][ONE_COPY_ROW])
    stages = result["breakdown_ms"]
    assert set(stages) == {"batch step", *STEP_PHASES, MEASUREMENT, "gc", "rest"}
    assert_stages(stages)
    text = format_vector_bench(result)
    assert "top_observer 8 UGVs switching, num_envs=3" in text and "localiser" in text


def assert_stages(stages):
    """Every phase and the measurement timed (each > 0), and within the batch step."""
    parts = [value for key, value in stages.items() if key not in ("batch step", "gc", "rest")]
    assert len(parts) == len(STEP_PHASES) + 1 and all(value > 0 for value in parts)
    assert stages["gc"] >= 0.0
    assert sum(parts) + stages["gc"] <= stages["batch step"]


def test_the_vector_bench_refuses_bad_sizes():
    with pytest.raises(ValueError, match="num_envs >= 1"):
        run_vector_bench([0])
    with pytest.raises(ValueError, match="workers >= 2"):
        run_vector_bench([4], workers=[1])
    with pytest.raises(SystemExit):
        main(["bench", "--vector", "--workers", "1"])
    with pytest.raises(SystemExit):
        main(["bench", "--vector", "--num-envs", "0"])


def test_the_memory_row_samples_the_start_and_even_points():
    samples = vector_memory(2, 8, samples=3)
    assert [done for done, _ in samples] == [0, 4, 8]
    assert all(mb > 0 for _, mb in samples)
    with pytest.raises(ValueError, match="env_steps >= num_envs"):
        vector_memory(4, 2)


def test_the_targets_are_judged_on_the_best_ratio_of_their_rows():
    result = {
        "num_envs": [1, 1024],
        "rates": {
            "top_observer switching, num_envs=1": [100.0, 90.0],
            "top_observer switching, num_envs=1024": [400.0, 300.0],
            "top_observer switching, 2 workers, num_envs=1024": [800.0, 700.0],
            "top_observer 8 UGVs switching, num_envs=1024": [90.0, 99.0],
        },
        "ratios": {
            "top_observer switching, num_envs=1": [2.4, 2.6],
            "top_observer switching, num_envs=1024": [14.0, 3.0],
            "top_observer switching, 2 workers, num_envs=1024": [15.0, 1.0],
        },
    }
    lines = target_lines(result)
    assert lines == [
        "target >= 15x MPE2 at num_envs=1024: top_observer switching, num_envs=1024: 14.00x (missed)",
        "target >= 15x MPE2 at num_envs=1024: top_observer switching, 2 workers, num_envs=1024: 15.00x (met)",
        "target >= 2.5x MPE2 for one copy: top_observer switching, num_envs=1: 2.60x (met)",
        "target: 8 UGVs cost at most 4x the time of 2 (linear), num_envs=1024: 4.04x (missed)",
    ]
    # without MPE2 (no ratios) only the cost of added UGVs is judged
    assert target_lines({**result, "ratios": {}}) == lines[-1:]
    # the one-copy target is the PettingZoo env's, when the run timed it
    pettingzoo = {**result, "ratios": {**result["ratios"], "top_observer switching, PettingZoo env": [2.2, 2.4]}}
    assert target_lines(pettingzoo)[2] == "target >= 2.5x MPE2 for one copy: top_observer switching, PettingZoo env: 2.40x (missed)"


def test_a_second_breakdown_of_the_same_batch_times_its_stages_again():
    # A second measurement must time its own batch steps: not leave its stages at zero
    # (every second counted as the rest), nor add the first's, and the batch must step
    # untimed after each.
    import numpy as np

    from moma_env import vector
    from training.bench_vector import stage_breakdown

    envs = vector.make("top_observer", 2, action_mode="switching")
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    batches = [envs.sample_actions(rng) for _ in range(4)]
    first = stage_breakdown(envs, batches, 3)
    assert envs.phase_seconds is None
    second = stage_breakdown(envs, batches, 3)
    assert envs.phase_seconds is None
    for stages in (first, second):
        assert_stages(stages)
    envs.close()


def test_memory_is_judged_flat_on_the_samples_after_the_start():
    flat = {"num_envs": 4, "env_steps": 40, "rss_mb": [[0, 700.0], [10, 1000.0], [20, 1020.0], [40, 1000.0 * (1 + MEMORY_FLAT_FRACTION)]]}
    lines = memory_lines(flat)
    assert lines[1:5] == [
        "  after         0 env-steps  RSS    700.0 MB",
        "  after        10 env-steps  RSS   1000.0 MB",
        "  after        20 env-steps  RSS   1020.0 MB",
        "  after        40 env-steps  RSS   1050.0 MB",
    ]
    assert lines[-1].startswith("target: memory flat over 40 env-steps at num_envs=4: RSS 1000.0 MB after 10")
    assert lines[-1].endswith("(+5.0%; flat: within 5%) (met)")
    growing = {**flat, "rss_mb": [*flat["rss_mb"][:3], [40, 1051.0]]}
    assert memory_lines(growing)[-1].endswith("(missed)")
    assert memory_lines({**flat, "rss_mb": [*flat["rss_mb"][:3], [40, 949.0]]})[-1].endswith("(missed)")


def test_bench_vector_prints_the_memory_run_after_the_table(monkeypatch, capsys):
    """``moma-env bench --vector --memory-steps N``: the table's result and RSS over N env-steps
    at the largest batch, start included; fewer steps than copies is refused before any timing."""
    timed = []

    def table(num_envs, rounds, min_env_steps, workers):
        timed.append(list(num_envs))
        return {"rounds": 1, "min_env_steps": 1, "num_envs": list(num_envs), "rates": {}, "ratios": {},
                "breakdown_num_envs": 2, "breakdown_ms": {"batch step": 2.0, "localiser": 1.0}}

    monkeypatch.setattr(bench_vector, "run_vector_bench", table)
    assert main(["bench", "--vector", "--num-envs", "1", "2", "--memory-steps", "8", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert timed == [[1, 2]]
    assert result["memory"]["num_envs"] == 2 and result["memory"]["env_steps"] == 8
    assert [done for done, _ in result["memory"]["rss_mb"]] == [0, 2, 4, 6, 8]
    assert main(["bench", "--vector", "--num-envs", "2", "--memory-steps", "6"]) == 0
    text = capsys.readouterr().out
    assert "memory, top_observer switching, num_envs=2" in text and "target: memory flat over 6 env-steps" in text
    assert main(["bench", "--vector", "--num-envs", "2", "--memory-steps", "0"]) == 0
    assert "memory" not in capsys.readouterr().out
    assert main(["bench", "--vector", "--num-envs", "4", "--memory-steps", "3"]) == 2
    assert "--memory-steps must be 0 or at least the largest --num-envs (4)" in capsys.readouterr().err
    assert timed == [[1, 2], [2], [2]]
    with pytest.raises(SystemExit):
        bench_vector.main(["--num-envs", "4", "--memory-steps", "3"])
