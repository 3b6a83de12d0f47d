"""Every Python block of the getting-started page and of the README runs as written (each in
a fresh namespace)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "getting_started.md"
README = ROOT / "README.md"


def python_blocks(markdown: str) -> list[str]:
    """The code of every fenced ```python block of ``markdown``."""
    return re.findall(r"^```python\n(.*?)^```", markdown, re.M | re.S)


def test_python_blocks_are_found() -> None:
    assert python_blocks("x\n```python\na = 1\n```\n```bash\nls\n```\n") == ["a = 1\n"]


@pytest.mark.parametrize("index", range(len(python_blocks(PAGE.read_text(encoding="utf-8")))))
def test_getting_started_block_runs(index: int, capsys) -> None:
    code = python_blocks(PAGE.read_text(encoding="utf-8"))[index]
    exec(compile(code, f"{PAGE.name}[python block {index}]", "exec"), {"__name__": "__docs__"})
    assert capsys.readouterr().out.strip(), "each block prints what it shows"


@pytest.mark.parametrize("index", range(len(python_blocks(README.read_text(encoding="utf-8")))))
def test_readme_block_runs(index: int) -> None:
    code = python_blocks(README.read_text(encoding="utf-8"))[index]
    namespace = {"__name__": "__docs__"}
    exec(compile(code, f"README.md[python block {index}]", "exec"), namespace)
    assert "observations" in namespace
