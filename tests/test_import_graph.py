"""guidedarm's import graph: no import cycle among the modules of guidedarm.systems and
guidedarm.diagrams (read statically, function-level imports included), and the task
registry imports only the task it is asked for."""

from __future__ import annotations

import ast
import subprocess
import sys

from conftest import REPO

from guidedarm.diagrams.tasks.registry import AvailableTasks, TaskNames

# The distribution's packages and their folders (pyproject.toml's package-dir).
PACKAGES = {"guidedarm.systems": "systems", "guidedarm.diagrams": "diagrams"}


def _ModuleNames() -> dict[str, str]:
    """Dotted name -> path (relative to the repository) of every module of PACKAGES; a
    package is named by its __init__.py."""
    modules = {}
    for package, folder in PACKAGES.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            parts = list(path.relative_to(REPO / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join([package, *parts])] = str(path.relative_to(REPO))
    return modules


def _Imported(node: ast.ImportFrom | ast.Import, module: str, is_package: bool) -> list[str]:
    """The dotted names an import statement of `module` reads: `from X import a` names
    X.a (a submodule) and X; relative imports resolved."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = node.module or ""
    if node.level:
        parts = module.split(".")
        anchor = parts if is_package else parts[:-1]
        anchor = anchor[: len(anchor) - node.level + 1]
        base = ".".join([*anchor, base]) if base else ".".join(anchor)
    return [base, *(f"{base}.{alias.name}" for alias in node.names)]


def ImportGraph() -> dict[str, set[str]]:
    """module -> the modules of PACKAGES it imports anywhere in its file (module level,
    functions, `if TYPE_CHECKING:` blocks). `from X import a` is an edge to the submodule
    X.a when there is one, else to X; a package's __init__ is not an edge of its
    submodules (Python runs it first, but it is not what they read)."""
    modules = _ModuleNames()
    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        is_package = path.endswith("__init__.py")
        edges = set()
        for node in ast.walk(ast.parse((REPO / path).read_text())):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            names = _Imported(node, module, is_package)
            submodules = [n for n in names[1:] if n in modules]
            if isinstance(node, ast.ImportFrom) and submodules:
                edges.update(submodules)
            elif isinstance(node, ast.ImportFrom):
                edges.update(n for n in names[:1] if n in modules)
            else:
                edges.update(n for n in names if n in modules)
        graph[module] = edges - {module}
    return graph


def FindCycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle [a, b, ..., a] of the graph, or None (depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: finished
    path: list[str] = []

    def Visit(module: str) -> list[str] | None:
        state[module] = 1
        path.append(module)
        for target in sorted(graph.get(module, ())):
            if state.get(target) == 1:
                return [*path[path.index(target) :], target]
            if target not in state:
                cycle = Visit(target)
                if cycle:
                    return cycle
        path.pop()
        state[module] = 2
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = Visit(module)
            if cycle:
                return cycle
    return None


def test_no_import_cycle():
    graph = ImportGraph()
    assert len(graph) > 150  # every module was read
    assert (
        "guidedarm.diagrams.tasks.path_following.scenario"
        in graph["guidedarm.diagrams.tasks.path_following.setup"]
    )
    cycle = FindCycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_find_cycle_names_the_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}
    assert FindCycle(graph) == ["a", "b", "c", "a"]
    graph["c"] = {"d"}
    assert FindCycle(graph) is None


def test_get_task_imports_only_its_task():
    code = (
        "import sys\n"
        "from guidedarm.diagrams.tasks.registry import GetTask, TaskNames\n"
        "print(GetTask('joint_tour').name)\n"
        "prefix = 'guidedarm.diagrams.tasks.'\n"
        "print(sorted(n for n in TaskNames() if prefix + n in sys.modules))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO
    )
    assert result.stdout.split("\n")[:2] == ["joint_tour", "['joint_tour']"]


def test_every_task_package_defines_its_task():
    names = TaskNames()
    assert names == ["joint_tour", "marker_view", "panel_operation", "path_following", "waypoints"]
    assert sorted(task.name for task in AvailableTasks().values()) == names
