"""The documentation site builds (``mkdocs build --strict``: a broken link or anchor, a page
missing from the navigation, a page in the navigation that does not exist or a docstring
mkdocstrings cannot read fails), every page of ``docs/`` is in the navigation, and every
relative link of the README resolves to a file of the repository."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

if os.environ.get("CI"):
    import mkdocs  # noqa: F401  (CI installs the docs extra: a missing one must fail, not skip)
else:
    pytest.importorskip("mkdocs", reason="the docs extra (pip install -e '.[docs]')")


def nav_pages(nav: object) -> list[str]:
    """Every page path of an mkdocs ``nav`` (nested lists and titled mappings)."""
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, list):
        return [page for item in nav for page in nav_pages(item)]
    if isinstance(nav, dict):
        return [page for value in nav.values() for page in nav_pages(value)]
    raise TypeError(f"unexpected nav entry {nav!r}")


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    site = tmp_path / "site"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
           "NO_MKDOCS_2_WARNING": "1"}
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"), "--site-dir", str(site)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "WARNING" not in result.stderr, result.stderr
    # the generated pages and the API reference are there, with their content
    home = (site / "index.html").read_text(encoding="utf-8")
    assert "make square" in home
    top = (site / "configurations" / "top_observer" / "index.html").read_text(encoding="utf-8")
    assert "ugv_0" in top and "goal_spread" in top
    api = (site / "api" / "env" / "index.html").read_text(encoding="utf-8")
    assert "MomaParallelEnv" in api and "EnvConfig" in api
    assert ":class:" not in api and "``" not in api, "Sphinx roles made code spans (training/docs_griffe.py)"


def test_every_docs_page_is_in_the_nav() -> None:
    from mkdocs.config import load_config

    config = load_config(str(ROOT / "mkdocs.yml"))
    listed = set(nav_pages(config["nav"]))
    generated = {"index.md", "cli_reference.md"} | {p for p in listed if p.startswith("configurations/")}
    written = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert written - listed == set(), "pages of docs/ missing from mkdocs.yml's nav"
    assert listed - written - generated == set(), "nav entries that are neither in docs/ nor generated"
    assert not written & generated, "a generated page also has a file in docs/"


def relative_links(markdown: str) -> list[str]:
    """Targets of the Markdown links and images of ``markdown`` that are repository paths
    (no scheme, no pure anchor), without their anchors."""
    targets = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", markdown)
    return [t.split("#", 1)[0] for t in targets if not re.match(r"^[a-z]+:", t) and not t.startswith("#")]


def test_relative_links_finds_links_and_skips_web_and_anchors() -> None:
    text = "[a](docs/x.md#y) ![f](docs/f.png) [w](https://e.org/a.md) [t](#top) [b](Makefile)"
    assert relative_links(text) == ["docs/x.md", "docs/f.png", "Makefile"]


def test_readme_links_resolve() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    links = relative_links(readme)
    assert links, "the README links into the docs"
    missing = [link for link in links if not (ROOT / link).exists()]
    assert missing == [], f"README links to missing files: {missing}"


def test_readme_tables_cover_every_configuration_and_command() -> None:
    from moma_env.scenarios import SPECS
    from training.cli import build_parser

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for spec in SPECS:
        assert re.search(rf"^\| `{spec.name}` \|.*`{re.escape(spec.gymnasium_id)}` \|$", readme, re.M), spec.name
    commands = re.findall(r"^    ([a-z]+)\b", build_parser().format_help(), re.M)  # the COMMAND list of --help
    assert {"experiment", "bench", "evaluate", "train"} <= set(commands)
    for command in commands:
        assert f"| `moma-env {command}" in readme, command
