"""The small arrays of a batch's infos carried between processes as one array per place.

A worker of a sharded batch (:mod:`moma_env.vector.sharded`) sends its copies' infos to
the parent at every step. Pickled one by one, the small arrays in them (each UGV's 6x6
``"covariance"``, its ``"action_mask"``) cost more than the rest of the infos together:
each goes through numpy's reduction, and is rebuilt as an object of its own.

:func:`lift_arrays` takes, at every place ``infos[i][key][inner]`` where every copy ``i``
holds an array of the same shape and dtype, the copies' arrays out into one stacked array
(a column), leaving None in their places; the column crosses as one array. :func:`put_arrays`
puts each copy's row back in its place. The keys keep their order, and every value its
dtype, shape and bytes: the parent's infos are those of the worker, except that each of
these arrays is a row view of its column (an array that sat in two places comes back as two
views). The worker puts its own arrays back after the send (:func:`put_arrays` with the
lifted arrays), so its infos are left as they were.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["ArrayColumn", "lift_arrays", "put_arrays"]

#: One lifted place: (top-level key, key within it, the copies' arrays stacked along axis 0).
ArrayColumn = tuple[Any, Any, np.ndarray]


def lift_arrays(infos: Sequence[dict]) -> tuple[tuple[ArrayColumn, ...], list[list[np.ndarray]]]:
    """Lift the arrays that every copy of ``infos`` holds at the same place into columns.

    ``infos``: one dict per copy (agent, or another top-level key -> a dict). A place
    ``(key, inner)`` is lifted when ``infos[i][key]`` is a plain dict for every ``i`` and
    ``infos[i][key][inner]`` a C-contiguous array of at least one dimension, of the same
    shape and dtype in every copy (and not of objects); its entries are set to None.

    Returns the columns and, per column, the arrays lifted (in copy order), which
    :func:`put_arrays` puts back.
    """
    if not infos:
        return (), []
    places = [
        (key, inner, value.shape, value.dtype)
        for key, entry in infos[0].items()
        if type(entry) is dict
        for inner, value in entry.items()
        if _liftable(value)
    ]
    columns: list[ArrayColumn] = []
    lifted: list[list[np.ndarray]] = []
    for key, inner, shape, dtype in places:
        arrays = []
        for info in infos:
            entry = info.get(key)
            value = entry.get(inner) if type(entry) is dict else None
            if type(value) is not np.ndarray or value.shape != shape or value.dtype != dtype or not value.flags.c_contiguous:
                break
            arrays.append(value)
        else:
            columns.append((key, inner, np.stack(arrays)))
            lifted.append(arrays)
    for key, inner, _ in columns:
        for info in infos:
            info[key][inner] = None
    return tuple(columns), lifted


def put_arrays(infos: Sequence[dict], columns: Sequence[ArrayColumn], rows: Sequence[Sequence[np.ndarray]] | None = None) -> None:
    """Put each column's arrays back in their places of ``infos`` (in copy order): ``rows``
    given, the arrays :func:`lift_arrays` lifted (the sender's own); else the rows of
    each column's stacked array (the receiver's)."""
    for k, (key, inner, stacked) in enumerate(columns):
        values = stacked if rows is None else rows[k]
        if len(values) != len(infos):
            raise ValueError(f"the column {key!r}/{inner!r} holds {len(values)} arrays for {len(infos)} copies")
        for info, value in zip(infos, values):
            info[key][inner] = value


def _liftable(value: object) -> bool:
    return type(value) is np.ndarray and value.ndim >= 1 and not value.dtype.hasobject and value.flags.c_contiguous
