"""The pages the documentation site makes from the code (training/docs_pages.py)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from moma_env.env.config import EnvConfig, RewardConfig
from moma_env.env.factory import parallel_env
from moma_env.env.rewards import REWARD_TERMS
from moma_env.scenarios import SPECS
from moma_env.scenarios.common import ScenarioConfig
from moma_env.tasks import TASKS
from training import docs_pages
from training.docs_pages import (
    DocsError,
    attribute_docs,
    home_page,
    options_table,
    rst_tables_as_text,
    rst_to_markdown,
    site_links,
)

ROOT = Path(__file__).resolve().parents[1]


def test_rst_roles_become_code_spans() -> None:
    text = "see :class:`~moma_env.sim.Frame`, :func:`moma_env.io.write_json` and ``x = 1``"
    assert rst_to_markdown(text) == "see `Frame`, `moma_env.io.write_json` and `x = 1`"
    fenced = "```text\na  b\n```"
    assert rst_to_markdown(fenced) == fenced


def test_rst_simple_tables_are_fenced_as_text() -> None:
    text = "Rows:\n\n===  ====\na    one\nb    two\n     more\n===  ====\n\nAfter."
    assert rst_tables_as_text(text) == "Rows:\n\n```text\n===  ====\na    one\nb    two\n     more\n===  ====\n```\n\nAfter."
    headed = "===  ===\nx    y\n===  ===\n1    2\n===  ==="
    assert rst_tables_as_text(headed) == "```text\n" + headed + "\n```"
    assert rst_tables_as_text("no table == here") == "no table == here"


def test_attribute_docs_reads_multi_name_entries_and_continuations() -> None:
    @dataclasses.dataclass
    class Example:
        """Example.

        Attributes:
            a, b: both sides (m),
                continued here.
            c: see :class:`~pkg.Thing`.

        Raises:
            ValueError: not an attribute.
        """

        a: float = 1.0
        b: float = 2.0
        c: int = 3

    docs = attribute_docs(Example)
    assert docs == {"a": "both sides (m), continued here.", "b": "both sides (m), continued here.", "c": "see `Thing`."}


def test_options_table_refuses_an_undocumented_field() -> None:
    @dataclasses.dataclass
    class Half:
        """Half documented.

        Attributes:
            known: documented.
        """

        known: int = 1
        unknown: int | None = None

    with pytest.raises(DocsError, match=r"Half\.unknown"):
        options_table(Half)
    table = options_table(Half, ["known"])
    assert "| `known` | `int` | `1` | documented. |" in table


def test_options_table_keeps_pipes_in_code_and_escapes_them_in_text() -> None:
    table = options_table(EnvConfig, ["max_cycles"])
    assert "`int | None`" in table

    @dataclasses.dataclass
    class Piped:
        """Piped.

        Attributes:
            x: a | b, or `c | d`.
        """

        x: int = 0

    assert "| a \\| b, or `c | d`. |" in options_table(Piped)


@pytest.mark.parametrize("spec", SPECS, ids=lambda spec: spec.name)
def test_configuration_page_names_every_agent_option_and_reward(spec) -> None:
    page = docs_pages.configuration_page(spec.name)
    for mode in docs_pages.ACTION_MODES:
        env = parallel_env(spec.name, action_mode=mode)
        for agent in env.possible_agents:
            assert f"| `{mode}` | `{agent}` |" in page
            # every observation feature of the agent is a row of its table
            for i, feature in enumerate(env.layout.features[agent]):
                assert f"| {i} | `{feature.name}` |" in page
    for field in dataclasses.fields(spec.config_type):
        if field.init:
            assert re.search(rf"^\| `{field.name}` \| ", page, re.M), field.name
    for term in REWARD_TERMS:
        assert f"| `{term.name}` | {getattr(RewardConfig(), term.name):g} |" in page
    assert spec.gymnasium_id in page and spec.pettingzoo_module in page
    has_observer = spec.config_type().scenario().world.uav is not None
    assert ("the observer, when it is an agent" in page) == has_observer
    for task in TASKS.values():
        assert (task.name in page) == (task.configuration == spec.name)


def test_every_configuration_field_and_env_option_is_documented() -> None:
    # a field added without an 'Attributes:' entry makes the site's build fail here first
    for spec in SPECS:
        docs = attribute_docs(spec.config_type)
        missing = [f.name for f in dataclasses.fields(spec.config_type) if f.init and f.name not in docs]
        assert missing == [], f"{spec.name}: {missing}"
    for cls in (EnvConfig, RewardConfig, ScenarioConfig):
        docs = attribute_docs(cls)
        assert [f.name for f in dataclasses.fields(cls) if f.init and f.name not in docs] == []


def test_configurations_index_lists_configurations_options_and_tasks() -> None:
    page = docs_pages.configurations_index()
    for spec in SPECS:
        assert f"[`{spec.name}`]({spec.name}.md)" in page
    for field in dataclasses.fields(EnvConfig):
        assert f"| `{field.name}` |" in page
    assert "| `render_mode` | `str | None` | `None` |" in page
    assert "| `random_scenarios` | `bool` | `False` |" in page
    for task in TASKS.values():
        assert f"| `{task.name}` | `{task.gymnasium_id}` |" in page


def test_unknown_configuration_is_one_clear_error() -> None:
    with pytest.raises(DocsError, match="unknown 'nope'"):
        docs_pages.configuration_page("nope")


def test_cli_page_has_every_command() -> None:
    from training.cli import build_parser

    page = docs_pages.cli_page()
    usage = build_parser().format_help()
    commands = re.findall(r"^    ([a-z]+)\b", usage, re.M)  # the COMMAND list of --help
    assert {"experiment", "bench", "evaluate", "train"} <= set(commands)
    for command in commands:
        assert f"## moma-env {command}" in page
    assert "## moma-env experiment square" in page and "--runs" in page


def test_cli_page_does_not_depend_on_the_terminal(monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "60")
    narrow = docs_pages.cli_page()
    monkeypatch.setenv("COLUMNS", "250")
    assert docs_pages.cli_page() == narrow


def test_home_page_rewrites_links_into_docs() -> None:
    readme = "![s](docs/square_paper.png) [e](docs/environments.md#tasks) [m](Makefile) [w](https://x.org/y)"
    assert home_page(readme) == "![s](square_paper.png) [e](environments.md#tasks) m (`Makefile`) [w](https://x.org/y)"


def test_site_links_point_readme_links_at_the_home_page() -> None:
    text = "[r](../README.md#the-environments) [p](../policies/README.md) [d](vector.md) [w](https://x.org)"
    assert site_links(text, "training.md") == "[r](index.md#the-environments) p (`policies/README.md`) [d](vector.md) [w](https://x.org)"
    assert site_links("[r](../../README.md)", "api/env.md") == "[r](../index.md)"


def test_main_writes_every_page_whole(tmp_path: Path, capsys) -> None:
    out = tmp_path / "pages"
    assert docs_pages.main(["--out", str(out), "--readme", str(ROOT / "README.md")]) == 0
    written = {p.relative_to(out).as_posix() for p in out.rglob("*.md")}
    assert written == {"index.md", "cli_reference.md", "configurations/index.md", *(f"configurations/{s.name}.md" for s in SPECS)}
    assert docs_pages.main(["--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert docs_pages.main(["--out", str(tmp_path / "other"), "--readme", str(tmp_path / "missing.md")]) == 2
    assert not (tmp_path / "other").exists()
