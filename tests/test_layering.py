"""The packages' layering, read from every import statement of the code (function-level imports included):
``experiments`` (the Hydra plug-board) over ``eval`` (reads run folders) over ``tracker`` (the core); no import
cycle between packages; and the trackers never see the truth: their packages import no evaluation."""

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# A package's modules may not import these (by their first dotted names).
FORBIDDEN = {
    "tracker": ("experiments", "eval", "hydra", "omegaconf", "rerun"),
    "eval": ("experiments", "hydra", "omegaconf"),
}
# The packages that hold trackers: the truth reaches them by no import (the evaluation judges their outputs).
TRACKER_PACKAGES = ("tracker.abis", "tracker.hybrid", "tracker.tbf")


def modules(package: str) -> Iterator[tuple[str, Path]]:
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts), path


def imports(path: Path, module: str) -> set[str]:
    """Every module ``path`` imports, absolute, anywhere in it."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the module's own package
                base = module.split(".")[: -node.level if path.name != "__init__.py" else len(module.split("."))]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module
            found.add(prefix)
            found.update(f"{prefix}.{alias.name}" for alias in node.names)
    return found


def node_of(module: str) -> str | None:
    """The package a module belongs to for the cycle check: ``eval``, ``experiments``, or the core's subpackage
    (``tracker.tbf``) or top-level module (``tracker.registry``); None outside the project."""
    parts = module.split(".")
    if parts[0] in ("eval", "experiments"):
        return parts[0]
    if parts[0] != "tracker" or len(parts) < 2:
        return "tracker" if parts[0] == "tracker" else None
    return ".".join(parts[:2])


def project_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    known = {name for package in ("tracker", "eval", "experiments") for name, _ in modules(package)}
    for package in ("tracker", "eval", "experiments"):
        for module, path in modules(package):
            source = node_of(module)
            for imported in imports(path, module):
                if imported in known and (target := node_of(imported)) not in (None, source):
                    graph.setdefault(source, set()).add(target)
    return graph


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_a_package_imports_nothing_from_the_layers_above_it(package):
    offending = [
        f"{module} imports {imported}"
        for module, path in modules(package)
        for imported in sorted(imports(path, module))
        if imported.split(".")[0] in FORBIDDEN[package]
    ]
    assert not offending, offending


def test_the_trackers_import_no_evaluation():
    offending = [
        f"{module} imports {imported}"
        for package in TRACKER_PACKAGES
        for module, path in modules(package.replace(".", "/"))
        for imported in sorted(imports(path, module))
        if imported.startswith("tracker.evaluation")
    ]
    assert not offending, offending


def test_no_two_packages_import_each_other_however_indirectly():
    graph = project_graph()
    state: dict[str, str] = {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = "open"
        for target in sorted(graph.get(node, ())):
            if state.get(target) == "open":
                raise AssertionError(" -> ".join([*path[path.index(target) :], target]))
            if target not in state:
                visit(target, [*path, target])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])


def test_the_check_finds_a_cycle_and_an_upward_import(tmp_path):
    """The scanner itself: relative imports resolve, and a function-level import counts."""
    path = tmp_path / "m.py"
    path.write_text("def f():\n    from .sibling import x\n    import experiments.run\n")
    assert imports(path, "tracker.tbf.m") >= {"tracker.tbf.sibling", "tracker.tbf.sibling.x", "experiments.run"}
    assert node_of("tracker.tbf.filter") == "tracker.tbf" and node_of("tracker.registry") == "tracker.registry"
