"""``moma-env --help`` is light: the parser is built from names, not from the envs.

Every ``--help`` runs in a fresh process without importing torch, Stable-Baselines3,
OpenCV, pymunk, matplotlib or the env modules; the names the parser offers
(``--scenario``, ``--preset``, ``--camera``, ``--action-mode``) match the real
registries; the start-up benchmark (``moma-env bench --cli``) measures it.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from training import bench_cli
from training.cli import main
from training.cli_args import ACTION_MODE_NAMES, CAMERA_BACKEND_NAMES, ESTIMATOR_NAMES, PRESET_NAMES, SCENARIO_NAMES, TEAM_ACTION_NAMES

HEAVY = ("torch", "stable_baselines3", "sb3_contrib", "cv2", "pymunk", "matplotlib", "moma_env.scenarios", "moma_env.sim")
HELPS = [[], ["experiment"], *[["experiment", e] for e in ("square", "line", "flips", "consistency")], ["bench"], ["evaluate"], ["train"], ["sweep"]]


def test_every_help_imports_none_of_the_heavy_modules():
    code = (
        "import json, sys\n"
        "from training.cli import main\n"
        f"for argv in {HELPS!r}:\n"
        "    try:\n"
        "        main([*argv, '--help'])\n"
        "    except SystemExit as exit:\n"
        "        assert exit.code == 0, (argv, exit.code)\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r} or m in {HEAVY!r})))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(done.stdout.strip().splitlines()[-1]) == []
    assert "usage: moma-env train" in done.stdout and "exit status:" in done.stdout


def test_import_moma_env_registers_the_ids_without_the_simulator():
    code = (
        "import json, sys, gymnasium, moma_env\n"
        "ids = sorted(i for i in gymnasium.registry if i.startswith('moma_env/'))\n"
        f"print(json.dumps([ids, sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r} or m in {HEAVY!r})]))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    ids, heavy = json.loads(done.stdout)
    assert heavy == []
    assert "moma_env/TopObserver-v0" in ids and "moma_env/TopObserverTeam4-v0" in ids


def test_the_names_only_registry_matches_the_scenario_specs():
    from moma_env.registration import CONFIGURATION_NAMES, REGISTERED
    from moma_env.scenarios import SPECS

    assert [tuple(entry) for entry in REGISTERED] == [
        (spec.name, spec.gymnasium_id, spec.pettingzoo_module, spec.pettingzoo_id) for spec in SPECS
    ]
    assert CONFIGURATION_NAMES == tuple(spec.name for spec in SPECS)


def test_the_parser_offers_the_real_names():
    from moma_env.camera import CAMERA_BACKENDS
    from moma_env.env.config import ACTION_MODES, TEAM_ACTIONS
    from moma_env.estimator.registry import ESTIMATORS
    from moma_env.scenarios import CONFIGURATIONS
    from moma_env.tasks import TASKS
    from training.experiments.presets import PRESETS

    assert SCENARIO_NAMES == tuple(CONFIGURATIONS) + tuple(sorted(TASKS))
    assert CAMERA_BACKEND_NAMES == tuple(CAMERA_BACKENDS)
    assert PRESET_NAMES == tuple(sorted(PRESETS))
    assert sorted(ACTION_MODE_NAMES) == sorted(ACTION_MODES)
    assert TEAM_ACTION_NAMES == TEAM_ACTIONS
    assert ESTIMATOR_NAMES == tuple(ESTIMATORS)
    from training.experiments.compare import CAMERAS, EXPERIMENTS

    assert tuple(EXPERIMENTS) == ("square", "line") and tuple(CAMERAS) == CAMERA_BACKEND_NAMES


def test_scenario_choices_are_shown_in_help(capsys):
    for command in ("evaluate", "train"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert ", ".join(SCENARIO_NAMES) in text


def test_the_start_up_benchmark_times_fresh_processes(monkeypatch, capsys):
    monkeypatch.setattr(bench_cli, "CLI_ROWS", (("train",),))
    result = bench_cli.run_cli_bench(rounds=2)
    assert [row["command"] for row in result["rows"]] == ["python -c pass", "moma-env train --help"]
    for row in result["rows"]:
        assert 0.0 < row["best_s"] <= row["median_s"]
    table = bench_cli.format_cli_bench(result)
    assert "| `moma-env train --help` |" in table and "best and median of 2 rounds" in table
    with pytest.raises(ValueError, match="rounds"):
        bench_cli.run_cli_bench(0)
