"""``deferred_collection``: the garbage collector paused for a batch step and run once at its
end, as its own schedule would have; the collector's state is left as it was."""

from __future__ import annotations

import gc
import threading
import weakref
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from moma_env import vector
from moma_env.vector.collection import deferred_collection


class _Node:
    def __init__(self) -> None:
        self.me = self  # a reference cycle: only the collector frees it


@pytest.fixture
def low_threshold():
    """A youngest-generation threshold of 10, so that a few allocations make a collection due."""
    saved = gc.get_threshold()
    was_enabled = gc.isenabled()
    gc.enable()
    gc.collect()
    gc.set_threshold(10, *saved[1:])
    try:
        yield
    finally:
        gc.set_threshold(*saved)
        (gc.enable if was_enabled else gc.disable)()


@contextmanager
def _collections() -> Iterator[list[int]]:
    """The generations of the collections that start in the ``with`` body, in this thread (a
    collection another thread's allocations set off is that thread's), as they start."""
    starts: list[int] = []
    me = threading.get_ident()

    def callback(phase: str, info: dict) -> None:
        if phase == "start" and threading.get_ident() == me:
            starts.append(info["generation"])

    gc.callbacks.append(callback)
    try:
        yield starts
    finally:
        gc.callbacks.remove(callback)


def _cyclic_garbage(count: int) -> list[weakref.ref]:
    refs = []
    for _ in range(count):
        node = _Node()
        refs.append(weakref.ref(node))
    return refs


def test_the_collector_is_paused_in_the_body_and_collects_what_was_due_after(low_threshold):
    with _collections() as starts:
        with deferred_collection():
            assert not gc.isenabled()
            at_entry = len(starts)  # (entering the with statement may itself have made one due)
            refs = _cyclic_garbage(200)   # 20 times the threshold: 20 collections without the pause
            assert len(starts) == at_entry
            assert all(r() is not None for r in refs)
        assert gc.isenabled()
    assert len(starts) == at_entry + 1     # once, at the end
    assert all(r() is None for r in refs)   # and the cycles made in the body are gone


def test_nothing_runs_after_a_body_that_allocated_little():
    """The deferral forces no collection: with none due at the end of the body, none runs.
    (A threshold of 1,000 young objects: the collector's own callbacks, this test's and any
    another library registered, allocate too, so a low threshold could come due anyway.)"""
    saved = gc.get_threshold()
    was_enabled = gc.isenabled()
    gc.enable()
    gc.set_threshold(1000, *saved[1:])
    try:
        with _collections() as starts:
            gc.collect()  # the young generation empty right before the step (this collection is counted)
            before = len(starts)
            with deferred_collection():  # 4 tracked allocations of its own
                pass
        assert len(starts) == before
    finally:
        gc.set_threshold(*saved)
        (gc.enable if was_enabled else gc.disable)()


def test_a_disabled_collector_stays_disabled_and_runs_nothing(low_threshold):
    gc.disable()
    with deferred_collection():
        refs = _cyclic_garbage(50)
    assert not gc.isenabled()
    assert all(r() is not None for r in refs)   # not collected: the caller turned the collector off
    gc.enable()
    gc.collect()
    assert all(r() is None for r in refs)


def test_the_collector_comes_back_after_an_error(low_threshold):
    with pytest.raises(ZeroDivisionError):
        with deferred_collection():
            1 / 0
    assert gc.isenabled()


def test_a_batch_step_collects_at_most_once(low_threshold):
    envs = vector.make("top_observer", 8, max_cycles=20)
    envs.reset(seed=0)
    actions = envs.sample_actions(np.random.default_rng(0))
    with _collections() as starts:
        for _ in range(3):
            before = len(starts)
            envs.step(actions)
            assert len(starts) - before <= 1
            assert gc.isenabled()
    assert starts  # with a threshold of 10 every step made one due


def test_a_sharded_batch_step_reads_the_workers_replies_with_the_collector_paused(monkeypatch):
    """The workers' replies (every copy's infos, unpickled in this process) are read within
    the paused stretch of the batch step, as the local shard's copies are stepped, so the
    collector neither runs while they arrive nor promotes them; it runs once at the end."""
    from moma_env.vector import sharded

    paused: list[bool] = []
    receive = sharded._Shard.receive

    def watched(self):
        paused.append(not gc.isenabled())
        return receive(self)

    monkeypatch.setattr(sharded._Shard, "receive", watched)
    envs = vector.make("top_observer", 8, max_cycles=20, workers=2)
    try:
        envs.reset(seed=0)
        actions = envs.sample_actions(np.random.default_rng(0))
        was_enabled = gc.isenabled()
        gc.enable()
        try:
            paused.clear()
            for _ in range(3):
                envs.step(actions)
                assert gc.isenabled()
        finally:
            (gc.enable if was_enabled else gc.disable)()
        assert paused == [True, True, True]  # one worker, one reply a step
    finally:
        envs.close()
