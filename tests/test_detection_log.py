"""Detection logs (moma_env.estimator.log) and ``moma-env localise``: a recorded run replays
into the run's own estimates, bit for bit, and a bad log is refused naming its line."""

import dataclasses
import json
import math

import numpy as np
import pytest

from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator
from moma_env.estimator.log import (
    LOG_FORMAT,
    DetectionLogError,
    FrameRecord,
    OdometryRecord,
    RecordingFactory,
    RecordingLocaliser,
    StaticRecord,
    parse_detection_log,
    read_detection_log,
    recording_localiser,
)
from moma_env.estimator.registry import localiser_factory
from moma_env.metrics import read_tum
from moma_env.metrics.tum_covariance import read_covariances
from training.cli import main
from training.experiments.leapfrog_run import run_leapfrog, run_leapfrog_recorded
from training.experiments.square import SquareConfig
from training.localise import replay_trajectories


def same_bits(a, b) -> bool:
    return a is not None and b is not None and a.shape == b.shape and np.array_equal(np.ascontiguousarray(a).view(np.int64), np.ascontiguousarray(b).view(np.int64))


@pytest.mark.parametrize("estimator", ["moma", "ekf"])
def test_a_recorded_run_replays_into_its_own_estimates_bit_for_bit(estimator):
    """Every robot's trajectory and covariances from the replay are the run's; the EKF's
    log carries the wheel odometry it took; recording changes nothing of the run."""
    config = dataclasses.replace(SquareConfig(), max_time_s=10.0, localiser=estimator)
    recorded, text = run_leapfrog_recorded(config, 5)
    plain = run_leapfrog(config, 5)
    log = parse_detection_log(text.splitlines())
    assert log.estimator == config.estimator
    assert log.frames == len(recorded.trajectories["ugv_0"]["moma"]) - 1  # one sample before the first frame
    assert any(isinstance(r, OdometryRecord) for r in log.records) == (estimator == "ekf")
    replayed, localised = replay_trajectories(log, localiser_factory(estimator)(log.estimator))
    assert set(replayed) == set(recorded.trajectories) == {"ugv_0", "ugv_1", "uav"}
    for name, methods in recorded.trajectories.items():
        run, again, unrecorded = methods["moma"], replayed[name], plain.trajectories[name]["moma"]
        assert same_bits(run.times, again.times) and same_bits(run.poses, again.poses) and same_bits(run.covariances, again.covariances)
        assert same_bits(run.poses, unrecorded.poses) and same_bits(run.covariances, unrecorded.covariances)
        assert localised[name] == int(recorded.localised[name].sum())


def test_a_replay_on_another_estimator_runs_the_same_calls():
    config = dataclasses.replace(SquareConfig(), max_time_s=6.0)
    log = parse_detection_log(run_leapfrog_recorded(config, 2)[1].splitlines())
    moma, _ = replay_trajectories(log, MomaEstimator(log.estimator))
    fused, _ = replay_trajectories(log, localiser_factory("fused")(log.estimator))
    assert same_bits(moma["ugv_0"].times, fused["ugv_0"].times)
    assert np.nanmax(np.abs(moma["ugv_1"].poses - fused["ugv_1"].poses)) < 0.05  # one observer: nearly the same estimates


def test_the_commands_record_and_replay_a_run_into_the_same_files(tmp_path, capsys):
    out = tmp_path / "square"
    assert main(["experiment", "square", "--runs", "1", "--max-time", "6", "--record-detections", "--out", str(out)]) == 1  # time limit
    log_path = out / "detections" / "run_00.jsonl"
    assert log_path.exists() and read_detection_log(log_path).frames > 0
    capsys.readouterr()
    replay_dir = tmp_path / "replay"
    assert main(["localise", str(log_path), "--out", str(replay_dir), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["estimator"] == "moma" and summary["frames"] == read_detection_log(log_path).frames
    for robot in ("ugv_0", "ugv_1", "uav"):
        recorded = (out / "tum" / "run_00" / f"{robot}_moma.tum").read_text()
        assert (replay_dir / f"{robot}.tum").read_text() == recorded
        assert (replay_dir / f"{robot}.cov.txt").read_text() == (out / "tum" / "run_00" / f"{robot}_moma.cov.txt").read_text()
        assert len(read_tum(replay_dir / f"{robot}.tum")) == len(read_covariances(replay_dir / f"{robot}.cov.txt")[0])
    assert json.loads((replay_dir / "summary.json").read_text())["robots"]["ugv_0"]["localised"] > 0
    # against the run's ground truth: the experiment's own errors of the main robot
    assert main(["localise", str(log_path), "--out", str(tmp_path / "errors"), "--truth", str(out / "tum" / "run_00"), "--json"]) == 0
    errors = json.loads(capsys.readouterr().out)["robots"]
    run = json.loads((out / "summary.json").read_text())["runs"][0]["metrics"]["moma"]
    assert errors["ugv_0"]["against_truth"]["mean_error_m"] == run["mean_error"] and errors["ugv_0"]["against_truth"]["final_error_m"] == run["final_error"]
    assert errors["uav"]["against_truth"]["matched_fraction"] > 0.9
    assert main(["localise", str(log_path), "--out", str(tmp_path / "none"), "--truth", str(tmp_path)]) == 2
    assert "no ground-truth file" in capsys.readouterr().err
    # a folder holds one run: the same command again replaces it whole
    assert main(["localise", str(log_path), "--out", str(replay_dir)]) == 0


def _header(**estimator) -> str:
    return json.dumps({"format": LOG_FORMAT, "version": 1, "estimator": estimator})


ROBOT = {"kind": "robot", "name": "a", "boards": {"3": np.eye(4).tolist()}, "cameras": {}, "static": True,
         "initial_pose": np.eye(4).tolist(), "time": 0.0, "planar": False}
DETECTION = {"camera_id": "cam", "board_id": 3, "T_c_m": np.eye(4).tolist(), "corners_px": [], "marker_ids": [],
             "time": 0.1, "reprojection_error_px": None, "covariance": None, "persistent_covariance": None}


@pytest.mark.parametrize(
    "lines, words",
    [
        ([], "empty"),
        (["{not json"], ":1: not JSON"),
        (["[1, 2]"], ":1: a record must be a JSON object"),
        ([json.dumps({"format": "other"})], "not a detection log"),
        ([json.dumps({"format": LOG_FORMAT, "version": 2, "estimator": {}})], "version 2"),
        ([_header(windw=3)], "'estimator'"),
        ([_header(window=0)], ":1: estimator.window: must be >= 1"),
        ([_header(), json.dumps({"kind": "teleport"})], ":2: unknown record kind 'teleport'"),
        ([_header(), json.dumps({**ROBOT, "boards": {"x": np.eye(4).tolist()}})], ":2: 'boards': board id 'x' is not an integer"),
        ([_header(), json.dumps({**ROBOT, "initial_pose": [[1, 0], [0, 1]]})], ":2: 'initial_pose' must be 4x4 numbers, got shape (2, 2)"),
        ([_header(), json.dumps({**ROBOT, "static": "yes"})], ":2: 'static' must be true or false"),
        ([_header(), "", json.dumps({"kind": "frame", "time": 0.1, "detections": [{**DETECTION, "T_c_m": [1, 2, 3]}]})],
         ":3: detections[0]: 'T_c_m' must be 4x4 numbers"),
        ([_header(), json.dumps({"kind": "frame", "time": 0.1, "detections": [{**DETECTION, "board_id": 3.5}]})],
         "detections[0]: 'board_id' must be an integer"),
        ([_header(), json.dumps({"kind": "frame", "time": "soon", "detections": []})], ":2: 'time' must be a number"),
        ([_header(), json.dumps({"kind": "static", "name": "a", "static": True})], ":2: missing 'time'"),
        ([_header(), json.dumps({"kind": "odometry", "name": "a", "increment": [0, 0], "covariance": np.eye(3).tolist(), "time": 1})],
         "'increment' must be 3 numbers"),
    ],
)
def test_a_bad_log_is_refused_naming_its_line_and_field(lines, words):
    with pytest.raises(DetectionLogError) as err:
        parse_detection_log(lines, "run.jsonl")
    assert words in str(err.value)


def test_a_detections_fields_come_back_as_recorded():
    recorder = RecordingLocaliser(MomaEstimator(), EstimatorConfig())
    recorder.add_robot("a", boards={3: np.eye(4)}, static=True, initial_pose=np.eye(4), time=0.0)
    recorder.add_robot("b", cameras={"cam": np.eye(4)}, static=False, time=0.0)
    T = np.eye(4)
    T[:3, 3] = (0.1, -0.0, 1.0 / 3.0)
    cov = np.diag([1e-6, 2e-6, 3e-6, 1e-4, 2e-4, 3e-4])
    seen = Detection("cam", 3, T, np.array([[1.5, 2.25]] * 4), (7,), 0.1, covariance=cov, persistent_covariance=cov / 4)
    plain = Detection("cam", 3, T, np.empty((0, 2)), (), 0.2)
    recorder.update(0.1, iter([seen]))  # an iterator is read once, for both
    recorder.update(0.2, [plain])
    log = parse_detection_log(recorder.text().splitlines())
    frames = [r for r in log.records if isinstance(r, FrameRecord)]
    (got,), (bare,) = frames[0].detections, frames[1].detections
    assert same_bits(got.T_c_m, T) and math.copysign(1.0, got.T_c_m[1, 3]) == -1.0
    assert same_bits(got.covariance, cov) and same_bits(got.persistent_covariance, cov / 4)
    assert same_bits(got.corners_px, seen.corners_px) and got.marker_ids == (7,) and got.time == 0.1
    assert math.isnan(bare.reprojection_error_px) and bare.covariance is None and bare.corners_px.shape == (0, 2)
    assert "NaN" not in recorder.text()


def test_a_call_the_estimator_refuses_is_raised_and_not_recorded():
    factory = RecordingFactory(MomaEstimator)
    localiser = factory(EstimatorConfig())
    assert factory.made == [localiser] and not hasattr(localiser, "odometry")  # MOMA takes no odometry
    assert hasattr(RecordingFactory(localiser_factory("ekf"))(EstimatorConfig()), "odometry")
    ekf = localiser_factory("ekf")(EstimatorConfig())
    assert hasattr(recording_localiser(ekf, EstimatorConfig()), "odometry") and not hasattr(RecordingLocaliser(ekf, EstimatorConfig()), "odometry")
    localiser.add_robot("a", boards={3: np.eye(4)}, static=True, initial_pose=np.eye(4), time=0.0)
    before = list(localiser.lines)
    with pytest.raises(ValueError, match="finite"):
        localiser.update(math.nan, [])
    with pytest.raises(Exception, match="nope"):
        localiser.update(1.0, [Detection("nope", 3, np.eye(4), np.empty((0, 2)), (), 1.0)])
    assert localiser.lines == before


def test_the_command_refuses_a_missing_or_unrunnable_log(tmp_path, capsys):
    assert main(["localise", str(tmp_path / "missing.jsonl"), "--out", str(tmp_path / "out")]) == 2
    assert "missing.jsonl" in capsys.readouterr().err
    log = tmp_path / "unknown_camera.jsonl"
    frame = {"kind": "frame", "time": 0.1, "detections": [DETECTION]}
    log.write_text("\n".join([_header(), json.dumps(ROBOT), json.dumps(frame)]) + "\n")
    assert main(["localise", str(log), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "refused a record" in err and "cam" in err
    assert not (tmp_path / "out").exists()


def test_the_real_robot_example_of_the_docs_writes_a_log_localise_runs(tmp_path, monkeypatch, capsys):
    """The Python example of docs/estimator.md, run as written, then the command on its log."""
    import pathlib
    import re

    text = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "estimator.md").read_text()
    example = re.search(r"```python\n(import numpy as np\nfrom moma_env.estimator import Detection.*?)```", text, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "docs/estimator.md", "exec"), {})
    log = read_detection_log(tmp_path / "uav_run.jsonl")
    assert log.frames == 5
    assert main(["localise", "uav_run.jsonl", "--out", "out", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    # located from the static UGV's board once the outlier gate has its start (3 samples)
    assert summary["robots"]["uav"]["localised"] == 3 and summary["robots"]["ugv_0"]["localised"] == 6
    uav = read_tum(tmp_path / "out" / "uav.tum")
    assert len(uav) == 3 and np.allclose(uav.positions[-1], [-0.1, 0.01, 2.3], atol=1e-12)  # 2 m above the board, itself 0.3 m up


def test_frames_of_one_instant_give_one_sample_the_last_estimate():
    """Two cameras' images taken at the same time, sent as two updates: one sample."""
    recorder = RecordingLocaliser(MomaEstimator(), EstimatorConfig())
    recorder.add_robot("a", boards={3: np.eye(4)}, static=True, initial_pose=np.eye(4), time=0.0)
    recorder.add_robot("b", cameras={"c1": np.eye(4), "c2": np.eye(4)}, static=False, time=0.0)
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    flip[2, 3] = 2.0
    for k in range(1, 5):
        t = 0.04 * k
        recorder.update(t, [Detection("c1", 3, flip, np.empty((0, 2)), (), t)])
        recorder.update(t, [Detection("c2", 3, flip, np.empty((0, 2)), (), t)])
    log = parse_detection_log(recorder.text().splitlines())
    assert log.frames == 8
    trajectories, localised = replay_trajectories(log, MomaEstimator(log.estimator))
    assert trajectories["b"].times.tolist() == [0.0, 0.04, 0.08, 0.12, 0.16]
    assert same_bits(trajectories["b"].poses[-1], recorder.estimate("b").T_w_b) and localised["b"] >= 1


def test_an_env_episode_replays_into_the_envs_estimates_bit_for_bit():
    """A coordination task's episode (four UGVs under a UAV, the motion rules, random
    actions): the log of its estimator, replayed, gives the estimates the env reported
    at every step."""
    from moma_env.env.factory import parallel_env

    recording = RecordingFactory(MomaEstimator)
    env = parallel_env("top_observer_team4", localiser=recording)
    env.reset(seed=7)
    rng = np.random.default_rng(7)
    reported = [env.simulation.frame.estimates]
    for _ in range(120):
        if not env.agents:
            break
        env.step({a: int(rng.integers(env.action_space(a).n)) for a in env.agents})
        reported.append(env.simulation.frame.estimates)
    assert len(recording.made) == 1 and env.simulation.localiser is recording.made[0]
    log = parse_detection_log(recording.made[0].text().splitlines())
    assert log.frames == len(reported)
    replayed, _ = replay_trajectories(log, MomaEstimator(log.estimator))
    assert set(replayed) == set(reported[0])
    switches = sum(isinstance(r, StaticRecord) for r in log.records)
    assert switches > 0, "the episode switched robots"
    for name, trajectory in replayed.items():
        for k, estimates in enumerate(reported):
            want = estimates[name]
            if want.T_w_b is None:
                assert not trajectory.valid[k]
            else:
                assert same_bits(trajectory.poses[k], want.T_w_b) and same_bits(trajectory.covariances[k], want.covariance)


def test_evaluate_records_each_episodes_log_and_its_replay_scores_the_same(tmp_path, capsys):
    """``moma-env evaluate --record-detections``: one log per episode beside its TUM files;
    localised against the episode's truth, each UGV's ME and E_f are the episode's."""
    out = tmp_path / "ev"
    argv = ["evaluate", "--scenario", "top_observer_team4", "--policy", "greedy", "--episodes", "2", "--seed", "5",
            "--max-cycles", "150", "--out", str(out)]
    assert main([*argv, "--record-detections", "--json"]) == 0
    recorded = json.loads(capsys.readouterr().out)
    assert sorted(p.name for p in (out / "detections").iterdir()) == ["ep_000.jsonl", "ep_001.jsonl"]
    episodes = json.loads((out / "summary.json").read_text())["episodes"]
    for k in range(2):
        assert main(["localise", str(out / "detections" / f"ep_{k:03d}.jsonl"), "--out", str(tmp_path / f"r{k}"),
                     "--truth", str(out / "tum" / f"ep_{k:03d}"), "--json"]) == 0
        robots = json.loads(capsys.readouterr().out)["robots"]
        for name, episode in episodes[k]["robots"].items():
            assert robots[name]["against_truth"]["mean_error_m"] == episode["metrics"]["mean_error"]
            assert robots[name]["against_truth"]["final_error_m"] == episode["metrics"]["final_error"]
    # the same evaluation without recording: the same episodes
    assert main([*argv, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert {k: v for k, v in plain.items() if k not in ("files", "wall_time_s")} == {k: v for k, v in recorded.items() if k not in ("files", "wall_time_s")}


@pytest.mark.parametrize("copy_env", ["pickle", "deepcopy"])
def test_an_env_recording_its_estimator_copies_with_its_log(copy_env):
    """A copy of the env (the rollout policies copy envs) continues the same log as the original."""
    import copy
    import pickle

    from moma_env.env.factory import parallel_env

    env = parallel_env("top_observer_team4", localiser=RecordingFactory(MomaEstimator))
    env.reset(seed=1)
    for _ in range(5):
        env.step({a: 1 for a in env.agents})
    other = pickle.loads(pickle.dumps(env)) if copy_env == "pickle" else copy.deepcopy(env)
    for e in (env, other):
        for _ in range(5):
            e.step({a: 1 for a in e.agents})
    assert other.simulation.localiser is not env.simulation.localiser
    assert other.simulation.localiser.text() == env.simulation.localiser.text()
    assert parse_detection_log(env.simulation.localiser.text().splitlines()).frames == 11


def test_evaluate_records_the_estimator_it_was_given_and_keeps_it_in_its_options():
    from training.evaluation import evaluate

    logs: list[str] = []
    result = evaluate("top_observer", "scripted", 1, seed=3, max_cycles=30, detection_logs=logs, localiser="ekf")
    assert result.options == {"localiser": "ekf"} and len(logs) == 1
    records = parse_detection_log(logs[0].splitlines()).records
    assert any(isinstance(r, FrameRecord) for r in records)
