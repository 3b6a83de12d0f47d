"""Evaluation sweeps: every scenario x policy x seed cell, on a process pool or on Ray (``moma-env sweep``).

* :mod:`.spec`: :class:`SweepSpec` (the cells and the episode options), :class:`Cell`, ``"0:100"`` seed ranges.
* :mod:`.cells`: :func:`run_cell` and :func:`run_cells`, one episode per cell through the evaluation
  harness (:func:`training.evaluation.harness.evaluate`), the unit of work a backend ships.
* :mod:`.folder`: the sweep's folder: its spec, a lock, one result file per finished cell.
* :mod:`.backends`: the local process pool and Ray (a task per few cells, retried if its worker dies).
* :mod:`.table`: the results table (Parquet and CSV), the summary and the figure.
* :mod:`.run`: :func:`sweep`, from a spec to the written table, resumable.
* :mod:`.command`: ``add_sweep_parser``, the ``moma-env sweep`` subcommand.

Nothing here imports Ray at import time; :mod:`.backends` imports it when the Ray backend runs.
"""
