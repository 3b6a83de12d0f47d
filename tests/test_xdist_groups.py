"""``make test``'s ``--dist loadgroup`` keeps the tests of one ``xdist_group`` on one test process.

The suite relies on it: the Ray tests share one Ray. pytest-xdist 3.8 stops
grouping, silently, under pytest 9.2 (it marks a test's group in the node id, which
pytest 9.2 no longer reads back: pytest-dev/pytest-xdist#1386), hence the dev extra's
``pytest<9.2``. This runs a small suite of grouped tests on two processes and checks
where they ran.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

GROUPED_TESTS = textwrap.dedent(
    """
    import os
    import pytest

    pytestmark = pytest.mark.xdist_group("one")

    @pytest.mark.parametrize("i", range(6))
    def test_notes_its_process(i):
        folder = os.environ["GROUPED_TESTS_NOTES"]
        with open(os.path.join(folder, f"ran_{i}"), "w") as note:
            note.write(os.environ.get("PYTEST_XDIST_WORKER", "none"))
    """
)


def test_the_tests_of_one_group_run_on_one_process(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_grouped.py").write_text(GROUPED_TESTS)
    (suite / "test_other.py").write_text("def test_a():\n    pass\n\n\ndef test_b():\n    pass\n")
    notes = tmp_path / "notes"
    notes.mkdir()
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "2", "--dist", "loadgroup", "-p", "no:cacheprovider", "-q",
         f"--basetemp={tmp_path / 'base'}", str(suite)],
        capture_output=True, text=True, cwd=suite, timeout=300, env={**os.environ, "GROUPED_TESTS_NOTES": str(notes)},
    )
    assert done.returncode == 0, done.stdout + done.stderr
    ran = sorted(notes.glob("ran_*"))
    workers = {path.read_text() for path in ran}
    assert len(ran) == 6, done.stdout
    assert len(workers) == 1 and workers != {"none"}, f"one group ran on {sorted(workers)}"
