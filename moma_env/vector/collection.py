"""The cyclic garbage collector's work of a batch step, done once at its end.

A batch step of many copies keeps what each copy makes (its frame, its infos) until the
step returns. CPython's collector runs on allocation counts, so within one step of
1,024 copies it runs its youngest generation dozens of times and finds the first
copies' objects still alive each time: it promotes them to the oldest generation, and
full collections, which traverse every object of every copy, follow every few steps
(docs/vector.md measures what deferring it saves; ``python -m training.bench_vector``
times the collector as its own stage).

:func:`deferred_collection` pauses the collector for the step and, when it resumes it,
lets CPython run the collection its own schedule has made due by then, once, with its
own choice of generation (and its rule that keeps full collections rare in a large
heap). Objects that live one step then die young, and cyclic garbage is still collected
on CPython's schedule. The collector's settings are left as they were; with the
collector disabled (``gc.disable``) nothing changes. Results do not depend on it: the
collector frees only unreachable objects.
"""

from __future__ import annotations

import gc

__all__ = ["deferred_collection"]


class deferred_collection:  # noqa: N801 - used as the function it replaced: ``with deferred_collection():``
    """Pause automatic garbage collection for the ``with`` body, then let the collection
    that came due run, once (see the module docstring).

    A small class rather than a ``contextlib.contextmanager`` generator: entered once per
    batch step, it skips the generator's setup and teardown."""

    __slots__ = ("_paused",)

    def __init__(self) -> None:
        self._paused = False

    def __enter__(self) -> None:
        if gc.isenabled():
            gc.disable()
            self._paused = True

    def __exit__(self, *exc: object) -> None:
        if self._paused:
            self._paused = False
            gc.enable()
            # CPython checks its schedule when a tracked object is allocated: this allocation
            # runs the due collection now rather than somewhere in the caller's code.
            list()
