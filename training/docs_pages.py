"""Pages of the documentation site made from the code, so that they cannot drift from it.

``mkdocs build`` calls these through its hook (``training/docs_hooks.py``); each function
returns one Markdown page as a string:

* :func:`configuration_page`: one configuration (``top_observer``, ...): its ids, its
  agents and their action and observation spaces per action mode (read from envs built
  with the defaults), the motion rules and the views it requires, the reward terms with
  their default weights, its options (the configuration dataclass's fields with type,
  default and meaning), its random layouts and its tasks;
* :func:`configurations_index`: the table of configurations, the environment options, the
  reward weights, the nested camera and estimator options and the tasks;
* :func:`cli_page`: every ``moma-env`` command with its ``--help``;
* :func:`home_page`: the README with its links made relative to ``docs/``;

and :func:`site_links` rewrites the links of a hand-written page that leave ``docs/``
(to the README, to code), which work on GitHub, into links the site has.

Meanings come from the Google-style ``Attributes:`` sections of the dataclasses'
docstrings; a field without one raises :class:`DocsError`, which fails the build (and
``tests/test_docs_pages.py``), so a new option cannot be added undocumented.

``python -m training.docs_pages --out DIR`` writes the generated pages into a new folder
``DIR`` (whole or not at all), to read them without mkdocs.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import inspect
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "DocsError",
    "ACTION_MODES",
    "attribute_docs",
    "rst_to_markdown",
    "rst_tables_as_text",
    "options_table",
    "configuration_page",
    "configurations_index",
    "cli_page",
    "home_page",
    "site_links",
    "generated_pages",
    "main",
]

#: The env's action modes, in the order the pages show them (``moma_env.env.config.ACTION_MODES``).
ACTION_MODES = ("switching", "velocity")

#: Keywords of ``moma_env.env.factory.configuration_env`` that are not ``EnvConfig`` fields
#: (those are ``env_config``'s).
_CONSTRUCTOR_OPTIONS = {
    "render_mode": "`\"rgb_array\"` (the top-down view with truth, estimates, boards, goals, ropes and camera coverage, "
    "the first camera's image as an inset) or `\"human\"` (the same in a pygame window); None renders nothing.",
    "random_scenarios": "a new random layout of the same robots at every reset, drawn from the env's seeded generator "
    "(the configuration's `random`, keeping its team fields).",
}

#: Width (characters) of the command line page's ``--help`` texts.
_HELP_WIDTH = 100

_ROLE = re.compile(r":(?:class|func|meth|attr|data|mod|obj|exc|const):`~?([^`]+)`")
_LITERAL = re.compile(r"(?<!`)``([^`]+)``(?!`)")  # not the backticks of a ``` fence
_SECTION = re.compile(r"^(Args|Arguments|Attributes|Returns|Raises|Yields|Examples?|Notes?|See Also):\s*$")


class DocsError(ValueError):
    """A page cannot be made: the code lacks what it documents (one line naming what)."""


# ---------------------------------------------------------------------------- text helpers


def rst_to_markdown(text: str) -> str:
    """Sphinx roles and double-backtick literals of a docstring as Markdown code spans:
    ``:class:`~a.b.C``` -> ```C```, ``:func:`a.f``` -> ```a.f```, ````x```` -> ```x```."""

    def role(match: re.Match[str]) -> str:
        target = match.group(1)
        whole = match.group(0)
        return f"`{target.rsplit('.', 1)[-1]}`" if ":`~" in whole else f"`{target}`"

    return _LITERAL.sub(r"`\1`", _ROLE.sub(role, text))


_RST_BORDER = re.compile(r"^=+(?: +=+)+\s*$")


def rst_tables_as_text(text: str) -> str:
    """RST simple tables of a docstring (rows between ``=====  =====`` borders) fenced as
    ```` ```text ```` blocks, which Markdown would otherwise run together into one
    paragraph. A table ends at a border line followed by a blank line or the end."""
    lines = text.splitlines()
    out: list[str] = []
    inside = False
    for i, line in enumerate(lines):
        border = bool(_RST_BORDER.match(line))
        if border and not inside:
            out += ["```text", line]
            inside = True
            continue
        out.append(line)
        if border and inside and (i + 1 == len(lines) or not lines[i + 1].strip()):
            out.append("```")
            inside = False
    if inside:
        out.append("```")
    return "\n".join(out)


def _cell(text: str) -> str:
    """``text`` fit for one Markdown table cell: one line, pipes escaped outside code spans
    (Python-Markdown's tables keep a pipe inside backticks, and show a backslash there)."""
    parts = " ".join(text.split()).split("`")
    return "`".join(part if i % 2 else part.replace("|", "\\|") for i, part in enumerate(parts))


def _docstring(obj: Any) -> str:
    return inspect.cleandoc(obj.__doc__ or "")


def _section_lines(doc: str, section: str) -> list[str]:
    """The lines of a Google-style section (``Attributes``), de-indented once."""
    lines = doc.splitlines()
    out: list[str] = []
    inside = False
    for line in lines:
        header = _SECTION.match(line.strip()) if not line.startswith(" ") else None
        if header:
            inside = header.group(1) == section
            continue
        if inside:
            if line and not line.startswith(" "):
                break
            out.append(line)
    body = [line for line in out if line.strip()]
    indent = min((len(line) - len(line.lstrip()) for line in body), default=0)
    return [line[indent:] for line in out]


def attribute_docs(cls: type) -> dict[str, str]:
    """Field name -> its meaning (Markdown, one line) from the ``Attributes:`` sections of
    ``cls``'s docstring and its bases' (the class's own wins). An entry
    ``"a, b: meaning"`` documents both fields."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        entries: list[tuple[list[str], list[str]]] = []
        for line in _section_lines(_docstring(klass), "Attributes"):
            match = re.match(r"^([A-Za-z_][A-Za-z0-9_]*(?:\s*,\s*[A-Za-z_][A-Za-z0-9_]*)*)\s*(?:\([^)]*\))?\s*:\s?(.*)$", line)
            if match and not line.startswith(" "):
                names = [n.strip() for n in match.group(1).split(",")]
                entries.append((names, [match.group(2)]))
            elif entries:
                entries[-1][1].append(line.strip())
        for names, text in entries:
            meaning = _cell(rst_to_markdown(" ".join(text)))
            for name in names:
                docs[name] = meaning
    return docs


def _format_default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        value = f.default_factory()  # type: ignore[misc]
        if dataclasses.is_dataclass(value):
            return f"`{type(value).__name__}()`"
    else:
        return "required"
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return f"`{value:g}`" if "e" not in f"{value:g}" else f"`{value!r}`"
    return _cell(f"`{value!r}`")


def _type_name(f: dataclasses.Field) -> str:
    kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", repr(f.type))
    return _cell(f"`{kind}`")


def options_table(cls: type, fields: Iterable[str] | None = None, prefix: str = "") -> str:
    """A Markdown table of the dataclass ``cls``'s init fields (or of ``fields`` only):
    option, type, default, meaning; :class:`DocsError` naming the first field without a
    meaning in the ``Attributes:`` docstrings."""
    if not dataclasses.is_dataclass(cls):
        raise DocsError(f"{cls.__name__} is not a dataclass")
    docs = attribute_docs(cls)
    chosen = None if fields is None else set(fields)
    rows = ["| option | type | default | meaning |", "|---|---|---|---|"]
    for f in dataclasses.fields(cls):
        if not f.init or (chosen is not None and f.name not in chosen):
            continue
        meaning = docs.get(f.name)
        if not meaning:
            raise DocsError(f"{cls.__module__}.{cls.__qualname__}.{f.name} has no meaning in an 'Attributes:' docstring")
        rows.append(f"| `{prefix}{f.name}` | {_type_name(f)} | {_format_default(f)} | {meaning} |")
    return "\n".join(rows)


def _first_paragraph(doc: str) -> str:
    return " ".join(doc.split("\n\n", 1)[0].split())


def _space_text(space: Any) -> str:
    """A gymnasium space in one short line: ``Box(-1, 1, (4,), float32)`` (one bound for every
    entry), ``Box((30,), float32)`` (bounds per entry, in the tables below), ``Discrete(2)``,
    ``Dict(features: ..., image: ...)``."""
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        low, high = space.low.ravel(), space.high.ravel()
        if low.size and (low == low[0]).all() and (high == high[0]).all():
            return f"Box({low[0]:g}, {high[0]:g}, {space.shape}, {space.dtype})"
        return f"Box({space.shape}, {space.dtype})"
    if isinstance(space, spaces.Dict):
        return "Dict(" + ", ".join(f"{key}: {_space_text(sub)}" for key, sub in space.spaces.items()) + ")"
    return str(space)


def _space(space: Any) -> str:
    return _cell(f"`{_space_text(space)}`")


# ---------------------------------------------------------------------------- configurations


def _spec(name: str) -> Any:
    from moma_env.scenarios import SCENARIO_SPECS

    spec = SCENARIO_SPECS.get(name)
    if spec is None:
        raise DocsError(f"configuration: unknown {name!r}; known: {sorted(SCENARIO_SPECS)}")
    return spec


def _envs(name: str) -> dict[str, Any]:
    """Action mode -> a PettingZoo env of configuration ``name`` with its defaults."""
    from moma_env.env.factory import parallel_env

    return {mode: parallel_env(name, action_mode=mode) for mode in ACTION_MODES}


def _agent_role(env: Any, agent: str) -> str:
    if agent in env.observer_agents:
        return "an observer (UAV or hand-held camera)" if len(env.observer_agents) > 1 else "the observer (UAV or hand-held camera)"
    sled = {robot: sled for robot, sled in ((s.robot, s.name) for s in env.scenario.world.sleds)}.get(agent)
    return f"UGV towing `{sled}`" if sled else "UGV"


def _agents_table(envs: Mapping[str, Any]) -> str:
    rows = ["| mode | agent | role | action space | observation space |", "|---|---|---|---|---|"]
    for mode, env in envs.items():
        for agent in env.possible_agents:
            rows.append(
                f"| `{mode}` | `{agent}` | {_agent_role(env, agent)} | {_space(env.action_space(agent))} "
                f"| {_space(env.observation_space(agent))} |"
            )
    return "\n".join(rows)


def _observation_tables(envs: Mapping[str, Any]) -> str:
    """One table per agent of its observation vector (index, feature, bounds); an agent whose
    layout differs between modes gets a table per mode."""
    layouts: dict[str, list[tuple[str, list[Any]]]] = {}
    for mode, env in envs.items():
        for agent, features in env.layout.features.items():
            seen = layouts.setdefault(agent, [])
            if not any(features == other for _, other in seen):
                seen.append((mode, list(features)))
    parts = []
    for agent, versions in layouts.items():
        for mode, features in versions:
            modes = [m for m, env in envs.items() if env.layout.features.get(agent) == features]
            parts.append(f"#### `{agent}` ({', '.join(f'`{m}`' for m in modes)})\n")
            rows = ["| index | feature | low | high |", "|---|---|---|---|"]
            rows += [f"| {i} | `{f.name}` | {f.low:g} | {f.high:g} |" for i, f in enumerate(features)]
            parts.append("\n".join(rows) + "\n")
    return "\n".join(parts)


def _rewards_table(columns: Mapping[str, Mapping[str, float]] | None = None) -> str:
    """The reward terms (in summing order) with their default weights, plus a column of
    weights per entry of ``columns`` (title -> term -> weight; missing terms: the default)."""
    from moma_env.env.config import RewardConfig
    from moma_env.env.rewards import REWARD_TERMS

    columns = dict(columns or {})
    docs = attribute_docs(RewardConfig)
    defaults = {f.name: f.default for f in dataclasses.fields(RewardConfig)}
    titles = "".join(f" {title} |" for title in columns)
    rows = [f"| term | default weight |{titles} per |", "|---|---|" + "---|" * len(columns) + "---|"]
    for term in REWARD_TERMS:
        if term.name not in docs:
            raise DocsError(f"moma_env.env.config.RewardConfig.{term.name} has no meaning in an 'Attributes:' docstring")
        weights = "".join(f" {weights.get(term.name, defaults[term.name]):g} |" for weights in columns.values())
        rows.append(f"| `{term.name}` | {defaults[term.name]:g} |{weights} {docs[term.name]} |")
    return "\n".join(rows)


def _views_rows(views: Mapping[str, Sequence[str]]) -> str:
    if not views:
        return "none"
    return "; ".join(f"`{camera}` sees {', '.join(f'`{o}`' for o in owners)}" for camera, owners in views.items())


def _tasks_of(name: str) -> list[Any]:
    from moma_env.tasks import TASKS

    return [task for task in TASKS.values() if task.configuration == name]


def _task_table(tasks: Sequence[Any]) -> str:
    rows = ["| task | Gymnasium id | options | objective |", "|---|---|---|---|"]
    for task in tasks:
        options = ", ".join(_cell(f"`{k}={v!r}`") for k, v in task.options.items() if k != "rewards")
        rows.append(f"| `{task.name}` | `{task.gymnasium_id}` | {options} | {_cell(task.objective)} |")
    return "\n".join(rows)


def configuration_page(name: str) -> str:
    """The page of configuration ``name`` (see the module docstring); DocsError for an unknown
    name or an undocumented field."""
    import importlib

    from moma_env.env.actions import ACTION_MODE_TYPES
    from moma_env.scenarios.common import ScenarioConfig
    from moma_env.sim import rules

    spec = _spec(name)
    cls = spec.config_type
    config = cls()
    scenario = config.scenario()
    envs = _envs(name)
    module = importlib.import_module(cls.__module__)
    shared = [f.name for f in dataclasses.fields(ScenarioConfig) if f.init]
    own = [f.name for f in dataclasses.fields(cls) if f.init and f.name not in shared]

    out = [f"# Configuration `{name}`\n"]
    out.append(
        "This page is made from the code when the site is built (`training/docs_pages.py`): the spaces "
        "are those of envs built with the defaults, the options the fields of "
        f"`{cls.__module__}.{cls.__name__}`.\n"
    )
    out.append(rst_to_markdown(_docstring(module)) + "\n")
    out.append("## Ids\n")
    out.append("| what | value |\n|---|---|")
    out.append(f"| PettingZoo | `from moma_env import {spec.pettingzoo_module}`; `{spec.pettingzoo_module}.parallel_env()`, "
               f"`pettingzoo.make(\"parallel\", \"{spec.pettingzoo_id}\")` |")
    out.append(f"| Gymnasium (the team as one agent) | `gymnasium.make(\"{spec.gymnasium_id}\")`, `gymnasium.make_vec(\"{spec.gymnasium_id}\", num_envs)` |")
    out.append(f"| batched | `moma_env.vector.make(\"{name}\", num_envs)` |")
    out.append(f"| configuration class | `{cls.__module__}.{cls.__name__}` |")
    out.append(f"| scripted baseline | `{spec.scripted_policy or 'none'}` |")
    out.append(f"| planner schedule | `{spec.schedule or 'none'}` |")
    out.append(f"| episode length with the defaults | {scenario.max_cycles} steps (`max_cycles`) |\n")

    out.append("## Agents and spaces\n")
    has_observer = bool(scenario.world.uavs)
    observer_note = (
        " In `switching` mode the observer flies itself (its tracking controller, on the detections) unless "
        "`observer_agent=True`; in `velocity` mode it is an agent unless `observer_agent=False`."
        if has_observer
        else " This configuration has no observer: every camera is carried by a robot."
    )
    out.append(f"Every agent of every mode with the defaults.{observer_note}\n")
    out.append(_agents_table(envs) + "\n")
    out.append("### Actions\n")
    for mode in ACTION_MODES:
        text = rst_to_markdown(" ".join(_docstring(ACTION_MODE_TYPES[mode]).split()))
        text = text.removeprefix(f"`{mode}`:").strip()
        out.append(f"- `{mode}`: {text}")
    if has_observer:
        out.append("- the observer, when it is an agent: `Box(-1, 1, (4,))`: vx, vy, yaw rate, climb rate (times its limits).")
    out.append("")
    out.append("### Observations\n")
    out.append(
        "Every value comes from the estimator, the detections, the owner's declarations and the clock, "
        "never from the truth (see `moma_env.env.observations`). Positions are relative to the arena centre "
        "over its half-diagonal; the bounds below are the space's.\n"
    )
    out.append(_observation_tables(envs))

    out.append("## Rules\n")
    out.append(rst_to_markdown(_docstring(rules)) + "\n")
    out.append("In this configuration (defaults):\n")
    out.append(f"- dwell time at every switch: `dwell_s` = {config.dwell_s:g} s; a leg of `switching` mode: at most "
               f"`leg_length` = {config.leg_length:g} m;")
    out.append(f"- boards each camera must see at the start: {_views_rows(config.required_views())};")
    out.append(f"- boards each camera must keep in view while devices move (plan checker): "
               f"{_views_rows(spec.motion_views(scenario.world))};")
    out.append("- the team must stay within the observer's floor coverage (plan checker): "
               f"{'yes' if spec.observer_coverage else 'no'};")
    out.append(f"- a goal is reached within {config.goal_tolerance_m:g} m and {config.goal_tolerance_rad:g} rad "
               "(truth); the episode terminates when every goal is reached and is truncated after `max_cycles`.\n")

    out.append("## Rewards\n")
    out.append(
        "One team reward, the sum of weighted terms (`RewardConfig`; `infos[agent][\"reward_terms\"]` shows "
        "each). Pass `rewards={...}` to change weights.\n"
    )
    out.append(_rewards_table() + "\n")

    out.append("## Options\n")
    out.append(
        f"Keywords of `{spec.pettingzoo_module}.parallel_env(...)` besides the "
        "[environment options](index.md#environment-options); a bad value raises `ConfigError` naming the field "
        f"(`\"{name}.<field>\"`). Nested `camera` and `estimator` take mappings of their fields "
        "([camera and estimator options](index.md#camera-options)).\n"
    )
    out.append(f"### Fields of `{cls.__name__}`\n")
    out.append((options_table(cls, own) if own else "none") + "\n")
    out.append("### Fields every configuration has\n")
    out.append(options_table(cls, shared) + "\n")

    out.append("## Random layouts\n")
    out.append(f"`{cls.__name__}.random(rng)`, used by `random_scenarios=True`: "
               f"{rst_to_markdown(' '.join(_docstring(cls.random).split()))}\n")
    team = spec.team_fields
    kept = ", ".join(f"`{field}` ({low:g} to {high:g})" for field, (low, high) in team.items()) or "none (the team is fixed)"
    out.append(f"Fields random layouts keep: {kept}.\n")

    tasks = _tasks_of(name)
    out.append("## Tasks\n")
    if tasks:
        out.append("Named study settings of this configuration (`moma_env/tasks.py`); keywords override their options.\n")
        out.append(_task_table(tasks) + "\n")
        out.append("Their reward weights (the team objective):\n")
        out.append(_rewards_table({f"`{task.name}`": task.options.get("rewards", {}) for task in tasks}) + "\n")
    else:
        out.append("No named task uses this configuration.\n")
    return "\n".join(out)


def configurations_index() -> str:
    """The index of the configurations: their table, the environment options, the reward
    weights, the camera and estimator options, the tasks."""
    from moma_env.camera import CameraConfig
    from moma_env.env.config import EnvConfig, RewardConfig
    from moma_env.env.factory import configuration_env, env_config
    from moma_env.estimator import EstimatorConfig, OutlierGateConfig
    import moma_env.tasks as tasks_module
    from moma_env.scenarios import SPECS
    from moma_env.tasks import TASKS

    out = ["# Configurations\n"]
    out.append(
        "Made from the code when the site is built (`training/docs_pages.py`). Each configuration is a "
        "dataclass of `moma_env/scenarios/` with the defaults of the paper's system; a task is a configuration "
        "with the options of a study. What the env does in general (motion rules, action masks, infos): "
        "[The environments](../environments.md).\n"
    )
    rows = ["| configuration | Gymnasium id | PettingZoo | agents (`switching`) | agents (`velocity`) |", "|---|---|---|---|---|"]
    for spec in SPECS:
        envs = _envs(spec.name)
        agents = {mode: ", ".join(f"`{a}`" for a in env.possible_agents) for mode, env in envs.items()}
        rows.append(
            f"| [`{spec.name}`]({spec.name}.md) | `{spec.gymnasium_id}` | `{spec.pettingzoo_id}` "
            f"| {agents['switching']} | {agents['velocity']} |"
        )
    out.append("\n".join(rows) + "\n")

    out.append("## Environment options\n")
    out.append("Keywords of every constructor (`parallel_env`, `env`, `vector.make`, `gymnasium.make`), besides a "
               "configuration's fields.\n")
    keywords = [p.name for constructor in (env_config, configuration_env)
                for p in inspect.signature(constructor).parameters.values() if p.kind is p.KEYWORD_ONLY]
    env_fields = {f.name for f in dataclasses.fields(EnvConfig)}
    undocumented = [k for k in keywords if k not in env_fields and k not in _CONSTRUCTOR_OPTIONS]
    if undocumented:
        raise DocsError(f"env_config or configuration_env keyword {undocumented[0]!r} is neither an EnvConfig field nor described in training/docs_pages.py")
    out.append(options_table(EnvConfig, [k for k in keywords if k in env_fields]))
    parameters = inspect.signature(configuration_env).parameters
    for key in keywords:
        if key in _CONSTRUCTOR_OPTIONS:
            parameter = parameters[key]
            kind = parameter.annotation if isinstance(parameter.annotation, str) else getattr(parameter.annotation, "__name__", "")
            out.append(f"| `{key}` | {_cell(f'`{kind}`')} | `{parameter.default!r}` | {_CONSTRUCTOR_OPTIONS[key]} |")
    out.append("")

    out.append("## Reward weights\n")
    out.append(f"{rst_to_markdown(_first_paragraph(_docstring(RewardConfig)))} `rewards={{...}}` changes them.\n")
    out.append(options_table(RewardConfig) + "\n")

    out.append("## Camera options\n")
    out.append("`camera={...}` of every configuration (`CameraConfig`): every camera of the rig.\n")
    out.append(options_table(CameraConfig, prefix="camera.") + "\n")
    out.append("## Estimator options\n")
    out.append("`estimator={...}` of every configuration (`EstimatorConfig`).\n")
    out.append(options_table(EstimatorConfig, prefix="estimator.") + "\n")
    out.append("The outlier gate, `estimator={\"gate\": {...}}` (`OutlierGateConfig`):\n")
    out.append(options_table(OutlierGateConfig, prefix="estimator.gate.") + "\n")

    out.append("## Tasks\n")
    out.append(f"{rst_to_markdown(_first_paragraph(_docstring(tasks_module)))} "
               "Accepted wherever a configuration name is.\n")
    out.append(_task_table(list(TASKS.values())) + "\n")
    return "\n".join(out)


# ---------------------------------------------------------------------------- command line


def cli_page() -> str:
    """The ``moma-env`` page: a table of the commands, then each command's ``--help``."""
    from training.cli import build_parser, leaf_commands

    parser = build_parser()
    commands = leaf_commands(parser, parser.prog)
    if not commands:
        raise DocsError("training.cli.build_parser has no sub-commands")
    out = ["# Command-line reference: `moma-env`\n"]
    out.append(
        "Made from the parser (`training.cli.build_parser`) when the site is built, so every option is listed "
        "with its default. After `make test` or `make square`, the command is `.venv/bin/moma-env`.\n"
    )
    out.append("| command | what it does |\n|---|---|")
    for command, helptext, _ in commands:
        anchor = re.sub(r"[^a-z0-9]+", "-", command.lower()).strip("-")
        out.append(f"| [`{command}`](#{anchor}) | {_cell(helptext)} |")
    out.append("")
    for command, _, sub in commands:
        # a fixed width, so that the page does not depend on the terminal that builds it
        sub.formatter_class = functools.partial(sub.formatter_class, width=_HELP_WIDTH)
        out.append(f"## {command}\n")
        out.append("```text\n" + sub.format_help().rstrip() + "\n```\n")
    return "\n".join(out)


# ---------------------------------------------------------------------------- home


_LINK = re.compile(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)")


def home_page(readme: str) -> str:
    """The README as the site's home page (``docs/index.md``): links into ``docs/`` made
    relative to it, links to other files of the repository turned into their path as code
    (the site holds only ``docs/``); web links and anchors unchanged."""

    def link(match: re.Match[str]) -> str:
        bang, text, target = match.groups()
        if re.match(r"^[a-z]+://", target) or target.startswith(("#", "mailto:")):
            return match.group(0)
        if target.startswith("docs/"):
            return f"{bang}[{text}]({target[len('docs/'):]})"
        path = target.split("#", 1)[0]
        return f"{text} (`{path}`)" if text.strip("`") != path else text

    return _LINK.sub(link, readme)


def site_links(markdown: str, page: str) -> str:
    """A page of ``docs/`` as the site shows it: its links out of ``docs/`` (they work on
    GitHub) made site links. ``page`` is the page's path relative to ``docs/``
    (``"training.md"``). A link to the repository's ``README.md`` points at the home page
    (``index.md``, made from it; the anchor kept); a link to another file outside ``docs/``
    becomes its repository path as code. Links inside ``docs/`` and web links are unchanged."""
    import posixpath

    depth = posixpath.dirname(page)

    def link(match: re.Match[str]) -> str:
        bang, text, target = match.groups()
        if re.match(r"^[a-z]+://", target) or target.startswith(("#", "mailto:")):
            return match.group(0)
        path, _, anchor = target.partition("#")
        resolved = posixpath.normpath(posixpath.join("docs", depth, path))
        if resolved.startswith("docs/"):
            return match.group(0)
        if resolved == "README.md":
            home = posixpath.relpath("index.md", depth or ".")
            return f"{bang}[{text}]({home}{'#' + anchor if anchor else ''})"
        return f"{text} (`{resolved}`)" if text.strip("`") != resolved else f"`{resolved}`"

    return _LINK.sub(link, markdown)


# ---------------------------------------------------------------------------- all pages


def generated_pages(readme: str) -> dict[str, str]:
    """Site path (relative to ``docs/``) -> Markdown of every generated page."""
    from moma_env.scenarios import SPECS

    pages = {"index.md": home_page(readme), "cli_reference.md": cli_page(), "configurations/index.md": configurations_index()}
    for spec in SPECS:
        pages[f"configurations/{spec.name}.md"] = configuration_page(spec.name)
    return pages


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m training.docs_pages --out DIR [--readme README.md]``: write the generated
    pages into the new folder DIR (whole or not at all); 2 with one line on bad input."""
    import shutil
    import tempfile

    parser = argparse.ArgumentParser(prog="python -m training.docs_pages", description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="new folder for the pages (must not exist)")
    parser.add_argument("--readme", type=Path, default=Path("README.md"), help="the README made the home page (default README.md)")
    args = parser.parse_args(argv)
    if args.out.exists():
        print(f"--out: {args.out} exists; give a new folder", file=sys.stderr)
        return 2
    try:
        readme = args.readme.read_text(encoding="utf-8")
    except OSError as error:
        print(f"--readme: cannot read {args.readme}: {error.strerror}", file=sys.stderr)
        return 2
    try:
        pages = generated_pages(readme)
    except DocsError as error:
        print(f"docs_pages: {error}", file=sys.stderr)
        return 2
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{args.out.name}.", dir=args.out.parent))
    try:
        for path, text in pages.items():
            (tmp / path).parent.mkdir(parents=True, exist_ok=True)
            (tmp / path).write_text(text, encoding="utf-8")
        tmp.rename(args.out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    print(f"{len(pages)} pages in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
