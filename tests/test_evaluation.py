"""The evaluation harness (training/evaluation) and ``moma-env evaluate``."""

from __future__ import annotations

import csv
import json
import math
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

import moma_env.io
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.metrics import read_tum
from training.cli import main
from training.evaluation import PolicyLoadError, evaluate, load_policy, policy_label
from training.evaluation.harness import mean_std
from training.evaluation.video import GifRecorder

MAX_CYCLES = 40


class StubRandomPolicy:
    """A RandomPolicy stand-in: a seeded coin per UGV (switching mode)."""

    def __init__(self, seed: int | None = None):
        self.seed = seed
        self.rng = np.random.default_rng(seed)

    def reset(self, env, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, observations: dict, infos: dict) -> dict:
        return {agent: int(self.rng.integers(2)) for agent in observations}


class AlwaysAdvance:
    """Every UGV asks to advance at every step."""

    def reset(self, env, seed: int | None = None) -> None:
        pass

    def act(self, observations: dict, infos: dict) -> dict:
        return {agent: 1 for agent in observations}


@pytest.fixture
def fake_policies(monkeypatch):
    """``agents.policies`` replaced by stubs, so the CLI's loader path is exercised."""
    module = types.ModuleType("agents.policies")
    module.RandomPolicy = StubRandomPolicy
    module.scripted_policy = lambda configuration: AlwaysAdvance()
    monkeypatch.setitem(sys.modules, "agents.policies", module)
    return module


def _run_cli(args, capsys):
    code = main(["evaluate", *args])
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ core


def test_evaluate_counts_and_finite_metrics():
    result = evaluate("top_observer", StubRandomPolicy(), 2, seed=3, max_cycles=MAX_CYCLES)
    assert [ep.seed for ep in result.episodes] == [3, 4]
    assert result.robots == ("ugv_0", "ugv_1")
    s = result.summary
    assert s["n_episodes"] == 2
    for ep in result.episodes:
        assert ep.steps == MAX_CYCLES and ep.truncated and not ep.success
        assert math.isnan(ep.time_to_goal_s)
        assert ep.duration_s == pytest.approx(MAX_CYCLES / 25.0)
        assert ep.n_switches == sum(r.n_switches for r in ep.robots.values())
        for r in ep.robots.values():
            assert len(r.truth) == MAX_CYCLES + 1 == len(r.moma)
            assert r.distance_m == pytest.approx(r.truth.path_length())
            assert len(r.switch_times) <= r.n_switches
            assert math.isfinite(r.metrics.mean_error) and math.isfinite(r.metrics.final_error)
            assert r.metrics.switch_times == r.switch_times
    assert s["success_rate"] == 0.0
    assert s["time_to_goal_s"]["n"] == 0
    for name in result.robots:
        moma = s["robots"][name]["moma"]
        assert moma["n_runs"] == 2 and moma["n_failed"] == 0
        assert math.isfinite(moma["mean_final_error"]) and moma["mean_final_error"] < 0.2
        finals = [ep.robots[name].metrics.final_error for ep in result.episodes]
        assert moma["mean_final_error"] == pytest.approx(np.mean(finals))
        assert moma["std_final_error"] == pytest.approx(np.std(finals, ddof=1))


def test_switches_are_recorded_for_a_policy_that_moves():
    result = evaluate("top_observer", AlwaysAdvance(), 1, seed=0, max_cycles=60, random_scenarios=False)
    ep = result.episodes[0]
    assert ep.n_switches >= 1
    moved = [r for r in ep.robots.values() if r.distance_m > 0.01]
    assert moved, "advancing robots must travel"
    assert all(r.n_switches >= 1 and r.switch_times for r in moved)


class AlwaysHold:
    """Every UGV holds at every step."""

    def reset(self, env, seed: int | None = None) -> None:
        pass

    def act(self, observations: dict, infos: dict) -> dict:
        return {agent: 0 for agent in observations}


def test_a_robot_left_static_off_its_goal_with_a_start_allowed_is_timed_and_its_goal_distance_kept():
    held = evaluate("top_observer_team4_legs", AlwaysHold(), 1, seed=3, max_cycles=50).episodes[0]
    assert not held.success
    for name, robot in held.robots.items():
        goal = np.asarray(held.goals[name])
        start = robot.truth.poses[0][:2, 3]
        assert robot.goal_distance_m == pytest.approx(float(np.hypot(*(goal[:2] - start))), abs=1e-9)
        assert 0.0 <= robot.goal_heading_error_deg <= 180.0
        assert robot.startable_s == pytest.approx(held.duration_s)  # never started, its start always allowed
        row = held.row()
        assert row[f"{name}_startable_s"] == robot.startable_s and row[f"{name}_goal_distance_m"] == robot.goal_distance_m
    done = evaluate("top_observer_team4_legs", "greedy@1.5", 1, seed=1000000).episodes[0]
    assert done.success
    scenario = parallel_env("top_observer_team4_legs").scenario
    for robot in done.robots.values():  # every goal reached and then held: within the tolerances at the end
        assert robot.goal_distance_m <= scenario.goal_tolerance_m
        assert robot.goal_heading_error_deg <= math.degrees(scenario.goal_tolerance_rad)
        assert robot.startable_s < done.duration_s


def test_evaluate_is_deterministic():
    a = evaluate("caterpillar", StubRandomPolicy(), 2, seed=7, max_cycles=MAX_CYCLES)
    b = evaluate("caterpillar", StubRandomPolicy(), 2, seed=7, max_cycles=MAX_CYCLES)
    ja = json.dumps(moma_env.io.to_jsonable(a.to_dict()), sort_keys=True)
    jb = json.dumps(moma_env.io.to_jsonable(b.to_dict()), sort_keys=True)
    assert ja == jb
    c = evaluate("caterpillar", StubRandomPolicy(), 2, seed=8, max_cycles=MAX_CYCLES)
    assert json.dumps(moma_env.io.to_jsonable(c.to_dict()), sort_keys=True) != ja


def test_random_layouts_differ_fixed_layouts_repeat():
    rand = evaluate("top_observer", StubRandomPolicy(), 2, seed=0, max_cycles=5, random_scenarios=True)
    fixed = evaluate("top_observer", StubRandomPolicy(), 2, seed=0, max_cycles=5, random_scenarios=False)
    assert rand.episodes[0].goals != rand.episodes[1].goals
    assert fixed.episodes[0].goals == fixed.episodes[1].goals


def test_evaluate_rejects_bad_input():
    with pytest.raises(ConfigError, match="unknown configuration"):
        evaluate("nope", StubRandomPolicy(), 1)
    with pytest.raises(ValueError, match="episodes"):
        evaluate("top_observer", StubRandomPolicy(), 0)
    with pytest.raises(ValueError, match="seed"):
        evaluate("top_observer", StubRandomPolicy(), 1, seed=-1)


def test_load_policy(fake_policies, tmp_path):
    assert isinstance(load_policy("random", "top_observer", 5), StubRandomPolicy)
    assert load_policy("random", "top_observer", 5).seed == 5
    assert isinstance(load_policy("scripted", "caterpillar"), AlwaysAdvance)
    with pytest.raises(PolicyLoadError, match="unknown policy 'foo'"):
        load_policy("foo", "top_observer")
    model = tmp_path / "model.zip"
    model.write_bytes(b"not a model")
    with pytest.raises(PolicyLoadError, match="not a folder of a training run"):
        load_policy(str(model), "top_observer")
    with pytest.raises(PolicyLoadError, match="holds no manifest.json"):
        load_policy(str(tmp_path), "top_observer")
    assert policy_label(str(model)) == "model"
    del fake_policies.RandomPolicy
    with pytest.raises(PolicyLoadError, match="RandomPolicy"):
        load_policy("random", "top_observer")


@settings(max_examples=50, deadline=None)
@given(st.lists(st.one_of(st.floats(-1e6, 1e6), st.just(math.nan)), max_size=8))
def test_mean_std_ignores_nan(values):
    stat = mean_std(values)
    finite = [v for v in values if math.isfinite(v)]
    assert stat["n"] == len(finite)
    if finite:
        assert stat["mean"] == pytest.approx(np.mean(finite), abs=1e-6)
    else:
        assert math.isnan(stat["mean"])
    if len(finite) > 1:
        assert stat["std"] == pytest.approx(np.std(finite, ddof=1), abs=1e-6)
    else:
        assert math.isnan(stat["std"])


# ------------------------------------------------------------------ CLI and files


def test_cli_writes_every_output(fake_policies, tmp_path, capsys):
    out = tmp_path / "ev"
    code, stdout, _ = _run_cli(
        ["--scenario", "top_observer", "--policy", "random", "--episodes", "3", "--seed", "2",
         "--max-cycles", str(MAX_CYCLES), "--out", str(out), "--json"],
        capsys,
    )
    assert code == 0
    printed = json.loads(stdout)
    assert printed["n_episodes"] == 3 and printed["policy"] == "random"

    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "top_observer" and summary["policy"] == "random"
    assert summary["n_episodes"] == 3 and len(summary["episodes"]) == 3
    assert [e["seed"] for e in summary["episodes"]] == [2, 3, 4]
    assert summary["random_scenarios"] is True
    for key in ("success_rate", "lost_track_rate", "time_to_goal_s", "n_switches", "n_refused", "robots"):
        assert key in summary["summary"]
    for robot in ("ugv_0", "ugv_1"):
        moma = summary["summary"]["robots"][robot]["moma"]
        assert math.isfinite(moma["mean_final_error"]) and math.isfinite(moma["mean_mean_error"])

    with open(out / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3
    assert [int(r["seed"]) for r in rows] == [2, 3, 4]
    for r in rows:
        assert int(r["steps"]) == MAX_CYCLES
        for robot in ("ugv_0", "ugv_1"):
            for col in ("distance_m", "ME_m", "E_f_m", "mean_heading_error_deg"):
                assert math.isfinite(float(r[f"{robot}_{col}"]))

    for k in range(3):
        for robot in ("ugv_0", "ugv_1"):
            truth = read_tum(out / "tum" / f"ep_{k:03d}" / f"{robot}_truth.tum")
            moma = read_tum(out / "tum" / f"ep_{k:03d}" / f"{robot}_moma.tum")
            assert len(truth) == MAX_CYCLES + 1
            assert 0 < len(moma) <= MAX_CYCLES + 1
            assert np.all(np.hypot(*(truth.xy[-1] - moma.xy[-1])) < 0.2)

    figure = out / "top_observer.png"
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.rglob("*.tmp*"))


def test_cli_table_and_default_folder(fake_policies, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, stdout, _ = _run_cli(
        ["--scenario", "caterpillar", "--policy", "scripted", "--episodes", "1", "--fixed", "--max-cycles", "20"], capsys
    )
    assert code == 0
    assert "caterpillar / policy scripted" in stdout and "ugv_1" in stdout
    summary = json.loads((tmp_path / "runs/evaluate/caterpillar_scripted/summary.json").read_text())
    assert summary["random_scenarios"] is False


def test_cli_same_seed_same_summary(fake_policies, tmp_path, capsys):
    for name in ("a", "b"):
        args = ["--scenario", "caterpillar_sled", "--policy", "random", "--episodes", "2", "--seed", "11",
                "--max-cycles", "30", "--out", str(tmp_path / name)]
        assert _run_cli(args, capsys)[0] == 0
    assert (tmp_path / "a/summary.json").read_bytes() == (tmp_path / "b/summary.json").read_bytes()
    assert (tmp_path / "a/episodes.csv").read_bytes() == (tmp_path / "b/episodes.csv").read_bytes()


def test_cli_video_writes_a_gif(fake_policies, tmp_path, capsys):
    out = tmp_path / "vid"
    code, stdout, _ = _run_cli(
        ["--scenario", "caterpillar", "--policy", "random", "--episodes", "1", "--max-cycles", "12",
         "--video", "--out", str(out)],
        capsys,
    )
    assert code == 0
    gif = out / "caterpillar_episode_000.gif"
    assert gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    with Image.open(gif) as image:
        assert image.n_frames == 7  # 13 frames (reset + 12 steps), every 2nd kept
        assert image.width <= 320
    assert "video:" in stdout


def test_an_interrupted_second_run_leaves_the_first_runs_results_whole(fake_policies, tmp_path, capsys, monkeypatch):
    out = tmp_path / "crash"
    first = ["evaluate", "--scenario", "top_observer", "--policy", "random", "--episodes", "1", "--max-cycles", "10", "--out", str(out)]
    assert main(first) == 0
    before = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert "summary.json" in before and "episodes.csv" in before

    fsync = moma_env.io._fsync_file

    def crash_on_summary(path):
        # summary.json is written last: every other file of the second run is complete by then
        if Path(path).name.startswith(".summary."):
            assert Path(path).stat().st_size > 100  # its content was written, not yet renamed
            raise KeyboardInterrupt("simulated crash after writing the content")
        fsync(path)

    monkeypatch.setattr(moma_env.io, "_fsync_file", crash_on_summary)
    second = [*first[:-4], "--episodes", "2", "--out", str(out)]
    assert main(second) == 130  # Ctrl-C: exit status 130, one line
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("moma-env: interrupted")
    after = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # the first run's files, byte for byte; none of the second's beside them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crash"]  # no temporary folder left


def test_gif_recorder_interrupted_save_leaves_nothing(tmp_path, monkeypatch):
    recorder = GifRecorder(fps=25.0, stride=1)
    for k in range(3):
        recorder(np.full((40, 40, 3), 60 * k, dtype=np.uint8))
    assert len(recorder) == 3

    def half_save(self, fp, *args, **kwargs):
        Path(fp).write_bytes(b"GIF89a partial")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", half_save)
    with pytest.raises(OSError, match="disk full"):
        recorder.write(tmp_path / "x.gif")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="frames"):
        recorder(np.zeros((4, 4), dtype=np.uint8))
    with pytest.raises(ValueError, match="nothing to write"):
        GifRecorder(fps=25.0).write(tmp_path / "y.gif")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "top_observer", "--policy", "foo", "--episodes", "2"], "unknown policy 'foo'"),
    ],
)
def test_cli_bad_names_exit_2_with_one_line(fake_policies, args, message, capsys):
    code, stdout, err = _run_cli(args, capsys)
    assert code == 2
    assert stdout == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_cli_unknown_scenario_is_refused_by_the_parser_with_a_hint(fake_policies, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--scenario", "top_observer_tem4", "--episodes", "2"])
    assert exit_info.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "invalid choice: 'top_observer_tem4' is no scenario (did you mean 'top_observer_team4'?" in last


def test_cli_trained_policy_path_without_a_run_exits_2(tmp_path, capsys):
    model = tmp_path / "ppo.zip"
    model.write_bytes(b"")
    code, _, err = _run_cli(["--scenario", "top_observer", "--policy", str(model)], capsys)
    assert code == 2 and "not a folder of a training run" in err


@pytest.mark.parametrize("episodes", ["0", "-3", "two"])
def test_cli_bad_episode_count_is_an_argparse_error(episodes, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--scenario", "top_observer", "--episodes", episodes])
    assert exc.value.code == 2
    assert "--episodes" in capsys.readouterr().err


def test_cli_random_and_fixed_are_exclusive(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--scenario", "top_observer", "--random-scenarios", "--fixed"])
    assert exc.value.code == 2
