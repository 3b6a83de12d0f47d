"""The file pipeline baseline: every other robot of a file moves at once, between static neighbours."""

from __future__ import annotations

import pytest
from policy_guard import guarded

from agents.policies import CaterpillarMulti, FilePipelinePolicy
from moma_env.env.factory import parallel_env
from moma_env.scenarios import make_scenario, scenario_spec, view_neighbours

SEED = 100000  # the first held-out seed of the bent file's baselines table


def run(policy, seed: int) -> dict:
    """One episode of ``caterpillar_multi_bend4`` (truth-guarded infos), with what the test checks."""
    env = parallel_env("caterpillar_multi_bend4")
    observations, infos = env.reset(seed=seed)
    policy.reset(env, seed=seed)
    file = list(env.possible_agents)
    most_movers = 0
    neighbours_moving = lost = 0
    legs = {a: 0 for a in file}
    out_of_order = []
    terminations: dict[str, bool] = {}
    while env.agents:
        before = {a: infos[a]["static"] for a in infos}
        observations, _, terminations, _, infos = env.step(policy.act(observations, guarded(infos)))
        movers = [a for a in infos if not infos[a]["static"]]
        most_movers = max(most_movers, len(movers))
        neighbours_moving += sum(file.index(b) - file.index(a) == 1 for a in movers for b in movers)
        lost += sum(info["status"] == "lost" for info in infos.values())
        for a in movers:
            if before.get(a):
                legs[a] += 1
                k = file.index(a)
                # a follower starts only after the robot ahead took more legs; the leader
                # at most one leg ahead of the robot behind it
                if (k > 0 and legs[a] > legs[file[k - 1]]) or (k == 0 and legs[a] > legs[file[1]] + 1):
                    out_of_order.append((env.frame.time, a, dict(legs)))
    return {
        "success": bool(terminations) and all(terminations.values()), "time": env.frame.time, "movers": most_movers,
        "neighbours_moving": neighbours_moving, "lost": lost, "out_of_order": out_of_order, "legs": legs,
    }


def test_the_pipeline_moves_two_robots_apart_never_neighbours_and_beats_turn_taking():
    pipeline = run(FilePipelinePolicy(), SEED)
    turns = run(CaterpillarMulti(), SEED)
    assert pipeline["success"] and turns["success"]
    assert pipeline["movers"] == 2 and turns["movers"] == 1
    assert pipeline["neighbours_moving"] == 0
    assert pipeline["out_of_order"] == []
    assert pipeline["lost"] == 0
    assert pipeline["time"] < turns["time"]


def test_view_neighbours_are_the_file_and_nothing_under_a_top_observer():
    world = make_scenario("caterpillar_multi", n_ugvs=4).world
    shared = view_neighbours(world, scenario_spec("caterpillar_multi").motion_views(world))
    assert shared == {
        "ugv_0": {"ugv_1"}, "ugv_1": {"ugv_0", "ugv_2"}, "ugv_2": {"ugv_1", "ugv_3"}, "ugv_3": {"ugv_2"},
    }
    top = make_scenario("top_observer", n_ugvs=3).world
    assert all(not others for others in view_neighbours(top, scenario_spec("top_observer").motion_views(top)).values())


def test_view_neighbours_name_an_unknown_camera_or_owner():
    world = make_scenario("caterpillar_multi", n_ugvs=3).world
    with pytest.raises(ValueError, match="unknown camera 'uav/camera'"):
        view_neighbours(world, {"uav/camera": ("ugv_0",)})
    with pytest.raises(ValueError, match="'ugv_9', which is no UGV or sled"):
        view_neighbours(world, {"ugv_1/camera": ("ugv_9",)})


def test_the_pipeline_refuses_a_team_that_is_no_file():
    env = parallel_env("top_observer_team4")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="needs a file of robots"):
        FilePipelinePolicy().reset(env)


def test_evaluate_names_a_policy_that_refuses_the_scenario_in_one_line_and_writes_nothing(tmp_path, capsys):
    from training.cli import main

    out = tmp_path / "run"
    assert main(["evaluate", "--scenario", "top_observer_team4", "--policy", "pipeline", "--episodes", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]  # after the progress bar's lines
    assert last.startswith("moma-env evaluate: FilePipelinePolicy cannot act in this env:") and "needs a file of robots" in last
    assert "Traceback" not in err
    assert not out.exists()


def test_sweep_names_a_policy_that_refuses_the_scenario_in_one_line(tmp_path, capsys):
    from training.cli import main

    args = ["sweep", "--scenarios", "top_observer_team4", "--policies", "pipeline", "--seeds", "0:1", "--backend", "local",
            "--jobs", "1", "--out", str(tmp_path / "sweep")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "moma-env sweep: FilePipelinePolicy cannot act in this env:" in err and "Traceback" not in err
