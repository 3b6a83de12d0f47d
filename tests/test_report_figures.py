"""The result figures are readable: no text runs off the figure, legends sit outside
every panel, and the square's inset shows MOMA against the truth at the scale of
MOMA's final error.

Each figure is made by its command (``moma-env experiment square|line|consistency``,
``evaluate``), caught when it is saved, and drawn again to measure its artists in
pixels.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from training.cli import main


@pytest.fixture
def saved_figures(monkeypatch):
    """Every Figure saved while the test runs, in order."""
    figures: list[Figure] = []
    original = Figure.savefig

    def spy(self, *args, **kwargs):
        figures.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", spy)
    return figures


def _check_layout(fig: Figure) -> None:
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    frame = fig.bbox

    def inside(box, what: str) -> None:
        assert box.x0 >= frame.x0 - 1 and box.x1 <= frame.x1 + 1 and box.y0 >= frame.y0 - 1 and box.y1 <= frame.y1 + 1, (
            f"{what} runs off the figure: {box} outside {frame.bounds}"
        )

    for ax in fig.axes:  # what is drawn of a panel: its titles, labels, tick labels
        if ax.get_title():
            inside(ax.title.get_window_extent(renderer), f"title {ax.get_title()!r}")
        inside(ax.get_tightbbox(renderer), f"panel {ax.get_title()!r}")
    for legend in fig.legends:
        inside(legend.get_window_extent(renderer), "the legend")
    panels = [ax for ax in fig.axes if ax.get_label() != "inset_axes"]
    assert fig.legends, "the figure has no legend"
    for ax in panels:
        assert ax.get_legend() is None, f"a legend inside the panel {ax.get_title()!r}"
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent(renderer)), f"the legend covers the panel {ax.get_title()!r}"


def test_the_square_figure_fits_and_zooms_on_the_final_error(tmp_path, saved_figures, capsys):
    assert main(["experiment", "square", "--side", "0.5", "--runs", "1", "--out", str(tmp_path / "sq"), "--json"]) == 0
    import json

    results = json.loads(capsys.readouterr().out)
    (fig,) = saved_figures
    _check_layout(fig)
    trajectory = fig.axes[0]
    (inset,) = trajectory.child_axes
    half_mm = np.diff(inset.get_xlim())[0] / 2
    final_error_mm = 1000.0 * results["runs"][0]["metrics"]["moma"]["final_error"]
    assert final_error_mm < half_mm <= max(2.5 * final_error_mm, 2.0) + 1e-6  # both ends shown, at their scale
    assert half_mm < 0.05 * 500.0  # far closer than the 0.5 m square
    assert "final position" in inset.get_title()


def test_the_line_figure_fits(tmp_path, saved_figures):
    argv = ["experiment", "line", "--length", "1", "--passes", "2", "--switches-per-pass", "2", "--runs", "1", "--out", str(tmp_path / "ln")]
    assert main(argv) == 0
    (fig,) = saved_figures
    _check_layout(fig)


def test_the_observer_comparison_fits(tmp_path, saved_figures):
    assert main(["experiment", "square", "--side", "0.5", "--runs", "1", "--observer", "both", "--out", str(tmp_path / "ob")]) == 0
    assert len(saved_figures) == 3  # each observer's square, then the comparison
    for fig in saved_figures:
        _check_layout(fig)


def test_the_evaluation_figure_fits(tmp_path, saved_figures):
    argv = ["evaluate", "--scenario", "caterpillar_multi", "--policy", "random", "--episodes", "1", "--max-cycles", "20",
            "--out", str(tmp_path / "ev")]
    assert main(argv) == 0
    (fig,) = saved_figures
    _check_layout(fig)


def test_the_consistency_figures_fit(tmp_path, saved_figures):
    argv = ["experiment", "consistency", "--runs", "1", "--rendered-runs", "0", "--experiments", "square", "--max-time", "20",
            "--out", str(tmp_path / "cons")]
    assert main(argv) in (0, 1)  # 1: the time limit stopped the runs; the figures are drawn either way
    assert saved_figures
    for fig in saved_figures:
        _check_layout(fig)
