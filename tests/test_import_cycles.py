"""No import cycles among the modules of any package of the project.

Read statically from the sources, so every import counts: at module level, inside
functions and under ``TYPE_CHECKING`` alike (a cycle hidden in a function or a
type-checking block is still a cycle between two modules). Implicit imports of a
parent package are not edges (importing ``moma_env.world.config`` runs
``moma_env/world/__init__.py`` first, by Python's rules, not by choice).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Groups of modules that must import each other without a cycle: (package folder, file pattern).
GROUPS = {
    "moma_env": ("moma_env", "**/*.py"),
    "training": ("training", "**/*.py"),
    "agents": ("agents", "**/*.py"),
}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: Path, root: Path, known: set[str]) -> set[str]:
    """Modules of ``known`` that ``path`` (under ``root``) imports anywhere in its source."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        found.update(name for name in names if name in known)
    found.discard(name)
    return found


def import_graph(root: Path, folder: str, pattern: str) -> dict[str, set[str]]:
    """Module -> the modules of the same group it imports, for the files ``root/folder/pattern``."""
    paths = sorted((root / folder).glob(pattern))
    known = {module_name(p, root) for p in paths}
    return {module_name(p, root): imported_modules(p, root, known) for p in paths}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(module: str) -> list[str] | None:
        state[module] = 1
        path.append(module)
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                return path[path.index(target) :] + [target]
            if target not in state:
                cycle = visit(target)
                if cycle:
                    return cycle
        path.pop()
        state[module] = 2
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = visit(module)
            if cycle:
                return cycle
    return None


def test_the_cycle_finder_finds_a_cycle_and_only_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_sees_imports_in_functions_and_type_checking_blocks(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.b import B\n")
    (package / "b.py").write_text("def f():\n    from pkg import a\n    from .a import x\n")
    graph = import_graph(tmp_path, "pkg", "*.py")
    assert graph == {"pkg.a": {"pkg.b"}, "pkg.b": {"pkg.a"}}
    assert find_cycle(graph) == ["pkg.a", "pkg.b", "pkg.a"]


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_no_import_cycle(group):
    folder, pattern = GROUPS[group]
    graph = import_graph(ROOT, folder, pattern)
    assert len(graph) >= 3  # the group was found
    assert find_cycle(graph) is None


def test_moved_names_are_still_importable_from_where_they_were():
    from moma_env.world import arena, config, footprints
    from training import bench, bench_common

    for name in ("WALL_NAME", "obstacle_name"):
        assert getattr(arena, name) is getattr(config, name)
    for name in ("box_corners", "disk_overlaps_box", "disk_inside_rectangle", "boxes_overlap", "box_inside_rectangle"):
        assert getattr(arena, name) is getattr(footprints, name)
    # the names that lived in training.bench before training.bench_common took them (not the
    # helpers bench_common has gained since, which never lived there)
    for name in ("resident_mb", "time_calls", "steps_per_second", "best_of_rounds", "mpe2_reference"):
        assert name in bench_common.__all__
        assert getattr(bench, name) is getattr(bench_common, name)
