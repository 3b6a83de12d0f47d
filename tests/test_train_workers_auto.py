"""``moma-env train --workers auto`` (the default): how many processes a run's batch is split over."""

from __future__ import annotations

import argparse

import pytest

from training.cli import build_parser
from training.train import command_common
from training.train.command import config_from_args
from training.train.config import MIN_COPIES_PER_WORKER, auto_workers, usable_cores
from training.train.torchrl_command import torchrl_config_from_args


@pytest.mark.parametrize("envs, cores, expected", [
    (1, 2, None), (2, 2, None), (7, 2, None),  # fewer than two shards of MIN_COPIES_PER_WORKER: this process alone
    (8, 2, 2), (32, 2, 2), (1024, 2, 2),        # one process per core
    (8, 16, 2), (12, 16, 3), (64, 16, 16),      # at least MIN_COPIES_PER_WORKER copies each
    (64, 1, None),                              # one core: no worker
])
def test_auto_workers_is_one_per_core_with_enough_copies_each(envs, cores, expected):
    assert MIN_COPIES_PER_WORKER == 4  # the table above is written for it
    assert auto_workers(envs, cores) == expected


def test_usable_cores_counts_this_process_cores():
    assert 1 <= usable_cores()


def parse(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(["train", "--scenario", "top_observer_team4", "--out", "unused", *argv])


def test_the_default_is_auto_and_resolves_on_this_machine_cores(monkeypatch):
    monkeypatch.setattr(command_common, "usable_cores", lambda: 2)
    assert parse().workers == "auto"
    assert config_from_args(parse("--num-envs", "8")).workers == 2
    assert config_from_args(parse("--num-envs", "4")).workers is None
    monkeypatch.setattr(command_common, "usable_cores", lambda: 1)
    assert config_from_args(parse("--num-envs", "32")).workers is None


def test_auto_splits_both_routes_but_not_a_process_per_copy(monkeypatch):
    monkeypatch.setattr(command_common, "usable_cores", lambda: 4)
    assert config_from_args(parse("--num-envs", "16", "--route", "centralised")).workers == 4
    assert config_from_args(parse("--num-envs", "16", "--subproc")).workers is None
    assert config_from_args(parse("--num-envs", "16")).workers == 4


def test_the_torchrl_backend_resolves_auto_alike(monkeypatch):
    monkeypatch.setattr(command_common, "usable_cores", lambda: 2)
    args = parse("--backend", "torchrl", "--algo", "maskable_ppo", "--num-envs", "8")
    assert torchrl_config_from_args(args).workers == 2


def test_an_explicit_count_is_kept_whatever_the_machine(monkeypatch):
    monkeypatch.setattr(command_common, "usable_cores", lambda: 64)
    assert config_from_args(parse("--num-envs", "16", "--workers", "1")).workers == 1
    assert config_from_args(parse("--num-envs", "16", "--workers", "3")).workers == 3


@pytest.mark.parametrize("value, message", [("0", "worker count must be >= 1, got 0 (or 'auto')"),
                                            ("two", "expected an integer worker count, got 'two' (or 'auto')")])
def test_a_bad_worker_count_names_the_option_and_auto(capsys, value, message):
    with pytest.raises(SystemExit):
        parse("--workers", value)
    err = capsys.readouterr().err
    assert "--workers" in err and message in err
