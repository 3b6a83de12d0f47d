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
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["deferred_collection"]


@contextmanager
def deferred_collection() -> Iterator[None]:
    """Pause automatic garbage collection for the ``with`` body, then let the collection
    that came due run, once (see the module docstring)."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        # CPython checks its schedule when a tracked object is allocated: this allocation
        # runs the due collection now rather than somewhere in the caller's code.
        list()
