"""The cyclic garbage collector's work of a batch step, done once at its end.

A batch step of many copies keeps what each copy makes (its frame, its infos) until the
step returns. CPython's collector runs on allocation counts, so within one step of
1,024 copies it runs its youngest generation dozens of times and finds the first
copies' objects still alive each time: it promotes them to the oldest generation, and
full collections, which traverse every object of every copy, follow every few steps
(docs/vector.md measures what that cost: the ``gc`` stage of ``python -m
training.bench_vector``).

:func:`deferred_collection` pauses the collector for the step and afterwards runs the
one collection the collector would have run by then, once: the generation CPython's
own schedule names (the oldest whose count is over its threshold), when the youngest
generation's count is over its threshold. Objects that live one step then die young,
and cyclic garbage is still collected every step that allocated enough. The
collector's settings are left as they were; with the collector disabled (``gc.disable``)
nothing is run. Results do not depend on it: the collector frees only unreachable
objects.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["deferred_collection"]


@contextmanager
def deferred_collection() -> Iterator[None]:
    """Pause automatic garbage collection for the ``with`` body, then run the collection
    that was due, once (see the module docstring)."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        counts, thresholds = gc.get_count(), gc.get_threshold()
        if thresholds[0] > 0 and counts[0] > thresholds[0]:
            due = 0
            for generation in range(len(counts) - 1, 0, -1):
                if counts[generation] > thresholds[generation]:
                    due = generation
                    break
            gc.collect(due)
