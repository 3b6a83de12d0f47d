"""The benchmark harness (training.bench): what it counts, not how fast anything is."""

from __future__ import annotations

import math

import pytest
from gymnasium import spaces

from training.bench import bench_configurations, format_bench, steps_per_second


class CountingSpace(spaces.Discrete):
    """A Discrete space that counts its samples."""

    def __init__(self, n: int):
        super().__init__(n)
        self.samples = 0

    def sample(self, mask=None, probability=None):
        self.samples += 1
        return super().sample()


class FakeParallelEnv:
    """Two agents whose episodes last three steps; records what it is given."""

    possible_agents = ["a", "b"]

    def __init__(self):
        self.agents: list[str] = []
        self.spaces = {a: CountingSpace(4) for a in self.possible_agents}
        self.steps, self.resets, self.actions = 0, 0, []
        self.samples_while_stepping = 0

    def action_space(self, agent):
        return self.spaces[agent]

    def reset(self, seed=None, options=None):
        self.resets += 1
        self.agents = list(self.possible_agents)
        self._left = 3
        return {}, {}

    def step(self, actions):
        assert set(actions) == set(self.agents)
        self.samples_while_stepping = sum(s.samples for s in self.spaces.values())
        self.actions.append(dict(actions))
        self.steps += 1
        self._left -= 1
        if self._left == 0:
            self.agents = []
        return {}, {}, {}, {}, {}

    def close(self):
        pass


def test_steps_per_second_steps_resets_and_samples_before_the_clock():
    env = FakeParallelEnv()
    rate = steps_per_second(lambda: env, steps=10, pool=4)
    assert rate > 0.0 and math.isfinite(rate)
    assert env.steps == 10
    assert env.resets == 1 + 3  # the first reset, then one after each 3-step episode
    # Every sample was drawn before the first step: 4 joint actions x 2 agents.
    assert sum(s.samples for s in env.spaces.values()) == 8
    assert env.samples_while_stepping == 8
    # The pool is used in turn.
    assert env.actions[0] == env.actions[4] == env.actions[8]


def test_bench_configurations_reports_every_configuration_and_mode():
    rows = bench_configurations(steps=3)
    from moma_env.scenarios import CONFIGURATIONS

    assert {(r["env"], r["action_mode"]) for r in rows} == {(c, m) for c in CONFIGURATIONS for m in ("switching", "velocity")}
    assert all(r["steps_per_s"] > 0 for r in rows)
    text = format_bench(
        {
            "steps": 3,
            "mpe2_simple_spread_steps_per_s": None,
            "configurations": [dict(r, x_mpe2=None) for r in rows],
            "memory_steps": 0,
            "memory_mb": [],
            "cpu_count": 2,
        }
    )
    assert "top_observer" in text and "n/a" in text


def test_rounds_are_interleaved_and_each_row_reports_its_best_round(monkeypatch):
    pytest.importorskip("mpe2", reason="needs the 'dev' extra (the MPE2 row)")
    import training.bench as bench

    calls = []
    rates = iter(range(1, 1000))

    def fake_rate(make_env, steps, seed=0, pool=1000):
        env = make_env()
        calls.append(getattr(env, "metadata", {}).get("name"))
        env.close()
        return float(next(rates))

    monkeypatch.setattr(bench, "steps_per_second", fake_rate)
    rows = bench.bench_configurations(steps=3, rounds=3, include_mpe2=True)
    per_round = len(rows)
    assert len(calls) == 3 * per_round
    assert calls[:per_round] == calls[per_round : 2 * per_round]  # every round runs every row, in the same order
    assert rows[0]["env"] == "mpe2 simple_spread"
    for k, row in enumerate(rows):
        assert row["rounds_steps_per_s"] == [float(1 + k + r * per_round) for r in range(3)]
        assert row["steps_per_s"] == max(row["rounds_steps_per_s"])
    result = bench.run_bench(steps=3, memory_steps=0, rounds=2)
    assert result["rounds"] == 2 and len(result["mpe2_rounds_steps_per_s"]) == 2
    assert all(r["env"] != "mpe2 simple_spread" for r in result["configurations"])
    assert all(r["x_mpe2"] == r["steps_per_s"] / result["mpe2_simple_spread_steps_per_s"] for r in result["configurations"])
    assert "best of 2 interleaved rounds" in bench.format_bench(result)


def test_step_breakdown_accounts_for_the_whole_step():
    from training.bench_step import step_breakdown

    result = step_breakdown("top_observer", steps=60, warmup=5)
    assert set(result) == {"step", "camera", "estimator", "world", "rest"}
    # Episodes reset within the run (max_cycles is long, but every part was timed every step).
    assert all(result[k] > 0.0 for k in ("step", "camera", "estimator", "world"))
    assert result["rest"] == result["step"] - result["camera"] - result["estimator"] - result["world"]
    assert result["camera"] + result["estimator"] + result["world"] < result["step"]


def test_step_breakdown_prints_the_target_budget_from_mpe2_in_the_same_run(capsys):
    pytest.importorskip("mpe2")
    from training.bench_step import TARGET_X_MPE2, main, mpe2_step_us

    assert 0.0 < mpe2_step_us(steps=20) < 1e6
    assert main(["--steps", "30"]) == 0
    printed = capsys.readouterr().out.splitlines()
    lines = {line.split()[0]: line for line in printed}
    assert {"step", "camera", "estimator", "world", "rest", "mpe2", "budget", "skeleton"} <= set(lines)
    skeletons = [line for line in printed if line.startswith("skeleton")]
    assert len(skeletons) == 2 and "robots static" in skeletons[0] and "robots driven" in skeletons[1]
    mpe2_us, budget_us = float(lines["mpe2"].split()[1]), float(lines["budget"].split()[1])
    # Both are printed rounded to the microsecond.
    assert abs(budget_us - mpe2_us / TARGET_X_MPE2) <= 1.0


def test_skeleton_step_drives_the_robots_only_when_asked(monkeypatch):
    """The skeleton's two variants differ in what the world does: with ``mobile`` every
    robot's body is driven at every substep, otherwise none is."""
    from moma_env.world.ugv import UGVBody
    from training.bench_step import skeleton_step_us

    driven = []
    original = UGVBody.drive
    monkeypatch.setattr(UGVBody, "drive", lambda self: driven.append(self) or original(self))
    assert skeleton_step_us(steps=5, warmup=0) > 0.0
    assert driven == []
    assert skeleton_step_us(steps=5, warmup=0, mobile=True) > 0.0
    assert len(driven) > 0
