"""Layout helpers shared by the result figures: a legend outside the data, a zoom inset.

Every figure of the experiments and the evaluation is a matplotlib ``Figure`` with
``layout="constrained"``; these helpers keep its legends off the data (one legend
for the figure, below its panels, where the constrained layout makes room for it)
and show where two trajectories differ at the scale they differ (a zoom inset).
``tests/test_report_figures.py`` renders every figure and checks that no text
leaves the figure and no legend covers a panel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure

__all__ = ["legend_below", "zoom_inset"]


def legend_below(fig: Figure, axes: Sequence[Axes], extra: Sequence[tuple[Artist, str]] = (), ncol: int | None = None) -> None:
    """One legend for ``fig`` below every panel: the labelled artists of ``axes`` (each
    label once, first come) and then ``extra`` ``(artist, label)`` pairs (proxies for
    line styles that have no label of their own, e.g. the switches)."""
    handles: list[Artist] = []
    labels: list[str] = []
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            if label not in labels:
                handles.append(handle)
                labels.append(label)
    for handle, label in extra:
        handles.append(handle)
        labels.append(label)
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=ncol or min(len(handles), 6), fontsize=8, frameon=False)


def zoom_inset(
    ax: Axes,
    curves: Sequence[tuple[np.ndarray, dict]],
    centre: np.ndarray,
    half_width_m: float,
    bounds: Sequence[float],
    title: str,
) -> Axes:
    """An inset of ``ax`` showing ``curves`` around ``centre`` in mm.

    Args:
        ax: the panel (planar positions in m).
        curves: ``(xy, plot keywords)``: (N, 2) positions in m, drawn as offsets
            from ``centre`` in mm.
        centre: the (x, y) in m the inset is centred on.
        half_width_m: half the side of the square window shown, in m (> 0).
        bounds: ``(x, y, width, height)`` of the inset in ``ax``'s data coordinates (m).
        title: the inset's title.

    Returns:
        the inset axes; the window it shows is outlined on ``ax``.
    """
    if not half_width_m > 0.0:
        raise ValueError(f"half_width_m must be > 0, got {half_width_m!r}")
    centre = np.asarray(centre, dtype=float)
    inset = ax.inset_axes(list(bounds), transform=ax.transData)
    for xy, style in curves:
        offsets = 1000.0 * (np.asarray(xy, dtype=float) - centre)
        inset.plot(offsets[:, 0], offsets[:, 1], **style)
    half_mm = 1000.0 * half_width_m
    inset.set_xlim(-half_mm, half_mm)
    inset.set_ylim(-half_mm, half_mm)
    inset.set_aspect("equal")
    inset.tick_params(labelsize=6, pad=1)
    inset.set_xlabel("mm", fontsize=6, labelpad=0)
    inset.set_title(title, fontsize=7, pad=2)
    inset.grid(alpha=0.3)
    ax.indicate_inset(
        (centre[0] - half_width_m, centre[1] - half_width_m, 2 * half_width_m, 2 * half_width_m), inset, edgecolor="0.35"
    )
    return inset
