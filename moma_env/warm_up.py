"""Compile the package's kernels ahead of their first use: :func:`warm_up`.

The camera, estimator, geometry and observation kernels are compiled on their first call
and kept in an on-disk cache (:mod:`moma_env.kernel_cache`). On a fresh installation
the first env therefore spends most of a minute compiling before its
first reset returns, and every new process after that loads the compiled kernels in a
second or two. :func:`warm_up` pays that cost once, at set-up (``make setup`` runs
``moma-env warm-up``): it steps each configuration a few seeded steps in each action
mode, as a batch of one copy and of two (two copies' cameras are measured together, with
kernels of their own), so that what a user runs first finds its kernels compiled.

It changes nothing but the cache: the episodes it runs are thrown away, and a kernel
loaded from the cache runs the same code as one compiled on first use.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["WarmUpStep", "warm_up", "ACTION_MODES"]

#: The action modes each configuration is stepped in.
ACTION_MODES = ("switching", "velocity")


@dataclass(frozen=True)
class WarmUpStep:
    """One configuration in one action mode, warmed up: ``seconds`` of wall time, the
    first-time compiles included."""

    configuration: str
    action_mode: str
    seconds: float


def warm_up(configurations: Sequence[str] | None = None, steps: int = 25) -> list[WarmUpStep]:
    """Step each of ``configurations`` (default: every registered one) ``steps`` seeded
    random steps in each action mode, as a batch of one copy and of two.

    Returns the wall time of each (configuration, action mode), in the order run.
    Raises ConfigError (from the env) for an unknown configuration name, before any is run.
    """
    from moma_env import vector
    from moma_env.scenarios import CONFIGURATIONS, config_type

    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    names = list(CONFIGURATIONS) if configurations is None else list(configurations)
    for name in names:
        config_type(name)  # ConfigError naming an unknown configuration, before any compile
    done: list[WarmUpStep] = []
    for name in names:
        for mode in ACTION_MODES:
            start = time.perf_counter()
            rng = np.random.default_rng(0)
            for copies in (1, 2):  # one copy measures its camera alone, two together
                envs = vector.make(name, copies, action_mode=mode)
                envs.reset(seed=0)
                for _ in range(steps):
                    envs.step(envs.sample_actions(rng))
                envs.close()
            done.append(WarmUpStep(name, mode, time.perf_counter() - start))
    return done
