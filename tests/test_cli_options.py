"""The options of ``moma-env``: one meaning per name, defaults and choices in ``--help``,
refusals with a hint, and the documented exit statuses."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from training.cli import EXIT_STATUSES, build_parser, leaf_commands, main

DOCS = Path(__file__).resolve().parents[1] / "docs" / "cli.md"


def _options(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if action.option_strings and not isinstance(action, argparse._HelpAction):
            yield action


# (command path, parser) of every command that runs (the leaves of the tree)
COMMANDS = {tuple(line.split()[1:]): parser for line, _, parser in leaf_commands(build_parser(), "moma-env")}


def test_every_command_of_the_tree_is_listed():
    assert set(COMMANDS) == {
        ("experiment", "square"), ("experiment", "line"), ("experiment", "flips"), ("experiment", "consistency"),
        ("experiment", "compare"),
        ("bench",), ("evaluate",), ("localise",), ("train",), ("sweep",), ("warm-up",),
    }


def test_one_option_name_has_one_destination_everywhere():
    dests: dict[str, set[str]] = {}
    for parser in COMMANDS.values():
        for action in _options(parser):
            for option in action.option_strings:
                dests.setdefault(option, set()).add(action.dest)
    assert {option: d for option, d in dests.items() if len(d) > 1} == {}
    # the renamed clashes: training counts timesteps, a bench row counts env steps
    assert dests["--timesteps"] == {"timesteps"} and dests["--steps"] == {"steps"}
    train = {o for a in _options(COMMANDS[("train",)]) for o in a.option_strings}
    bench = {o for a in _options(COMMANDS[("bench",)]) for o in a.option_strings}
    assert "--steps" not in train and "--envs" not in train and {"--timesteps", "--num-envs"} <= train
    assert "--train-steps" not in bench and "--train-timesteps" in bench
    assert "--envs" not in {o for a in _options(COMMANDS[("experiment", "flips")]) for o in a.option_strings}


@pytest.mark.parametrize("command", sorted(COMMANDS), ids=" ".join)
def test_every_option_says_its_default_and_choices_in_help(command):
    parser = COMMANDS[command]
    for action in _options(parser):
        assert action.help, f"{command} {action.option_strings} has no help"
        if action.required:
            continue
        text = action.help % {"default": action.default} if "%(default)" in action.help else action.help
        if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)) and "default" not in text:
            continue  # a flag: off unless given
        assert "default" in text, f"{command} {action.option_strings}: no default in {text!r}"
    formatted = parser.format_help()
    for action in _options(parser):
        if action.choices:
            assert all(str(c) in formatted for c in action.choices)


def test_every_help_ends_with_the_exit_statuses():
    assert build_parser().epilog == EXIT_STATUSES
    for command, parser in COMMANDS.items():
        assert "exit status:" in parser.epilog and " 2  " in parser.epilog, command


def test_the_exit_statuses_are_documented_verbatim():
    text = DOCS.read_text(encoding="utf-8")
    assert EXIT_STATUSES.strip() in text


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["train", "--scenario", "top_observer", "--route", "centralized", "--out", "x"],
         "invalid choice: 'centralized' is no route (did you mean 'centralised'? choose from centralised, shared)"),
        (["train", "--scenario", "top_observr", "--out", "x"], "did you mean 'top_observer'?"),
        (["train", "--scenario", "top_observer", "--algo", "maskable-ppo", "--out", "x"], "did you mean 'maskable_ppo'?"),
        (["experiment", "square", "--observer", "quadrocopter"], "did you mean 'quadcopter'?"),
        (["train", "--scenario", "top_observer", "--pretrain", "gredy", "--out", "x"], "did you mean 'greedy'?"),
        (["train", "--scenario", "top_observer", "--steps", "5", "--out", "x"], "unrecognized arguments: --steps"),
    ],
)
def test_a_near_miss_is_refused_with_a_hint(argv, hint, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert hint in capsys.readouterr().err.strip().splitlines()[-1]


def test_a_run_stopped_by_its_time_limit_exits_1_with_its_outputs(tmp_path, capsys):
    out = tmp_path / "square"
    assert main(["experiment", "square", "--runs", "1", "--max-time", "1", "--out", str(out), "--json"]) == 1
    captured = capsys.readouterr()
    results = json.loads(captured.out)
    assert [run["completed"] for run in results["runs"]] == [False]
    assert (out / "summary.json").is_file()
    assert "not every run completed" in captured.err.strip().splitlines()[-1]
