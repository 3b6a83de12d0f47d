"""The sweep's figure: one legend of the policies, short labels for training folders."""

from __future__ import annotations

import warnings

from training.sweep.table import plot_summary, policy_labels


def test_training_folders_are_labelled_by_their_last_component_unless_two_share_it():
    assert policy_labels(["greedy@1.5", "runs/train/a_long_run_name", "random"]) == ["greedy@1.5", "a_long_run_name", "random"]
    assert policy_labels(["runs/x/run", "runs/y/run", "runs/z/other"]) == ["runs/x/run", "runs/y/run", "other"]


def test_long_policy_names_leave_the_layout_whole(tmp_path):
    cell = {"success_rate": 0.99, "e_f_m": {"mean": 0.007, "std": 0.005}, "n_episodes": 100}
    summary = [
        {"scenario": "top_observer_team4_legs", "policy": policy, **cell}
        for policy in ("greedy@1.5", "runs/train/team4_legs_rollout_nowait_bc_onestart_dagger_s0_ppo_kl3_daggerdemo")
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns when the constrained layout collapses
        plot_summary(summary, tmp_path / "sweep.png")
    assert (tmp_path / "sweep.png").stat().st_size > 0
