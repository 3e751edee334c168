"""The package's import graph, built statically from the source (no module is imported).

The rules of ``docs/architecture.md``: no import cycle (between modules, and
between the core's subpackages), no import of another module's ``_private``
name (nor a read of one through an imported module), no dynamic import anywhere in the package, and the numerical core never
imports ROS, message packages, matplotlib, the nodes, the command line, the
plots or ``execution`` (which, ROS-free too, may import only the core).  Each rule is also shown to catch a violation (the ``*_is_caught``
tests), so none of them can pass vacuously.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "flexmotion_ros"
CORE = f"{PACKAGE}.core"
EXECUTION = f"{PACKAGE}.execution"
FORBIDDEN_IN_CORE = ("rclpy", "matplotlib", f"{PACKAGE}.nodes", f"{PACKAGE}.cli", f"{PACKAGE}.plots")
MESSAGE_SUFFIXES = ("_msgs", "_srvs", "_interfaces")


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package (``pkg.__init__`` is ``pkg``)."""
    out = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _absolute(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(module: str, source: str, is_package: bool, known: set[str]) -> list[tuple[str, str | None]]:
    """``(imported module, imported name or None)`` for every import statement, function-level ones too."""
    found: list[tuple[str, str | None]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _absolute(module, is_package, node)
            for a in node.names:
                sub = f"{target}.{a.name}"
                found.append((sub, None) if sub in known else (target, a.name))
    return found


def graph(files: dict[str, Path]) -> dict[str, list[tuple[str, str | None]]]:
    known = set(files)
    return {m: imports_of(m, p.read_text(), p.name == "__init__.py", known) for m, p in files.items()}


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the directed graph as a list of nodes, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(edges.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m) :] + [m]
            if m not in state:
                cycle = visit(m)
                if cycle:
                    return cycle
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(edges):
        if n not in state:
            cycle = visit(n)
            if cycle:
                return cycle
    return None


def module_edges(g) -> dict[str, set[str]]:
    return {m: {t for t, _ in imps if t in g and t != m} for m, imps in g.items()}


def subpackage(module: str) -> str | None:
    """``flexmotion_ros.core.X...`` -> ``X`` for a core subpackage or module, else None."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and module.startswith(CORE + ".") else None


def package_edges(g) -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {}
    for m, imps in g.items():
        a = subpackage(m)
        if (
            a is None or m.count(".") < 3
        ):  # modules at the core's top (errors, config, ...) are not a layer of their own
            continue
        for t, _ in imps:
            b = subpackage(t)
            if b is not None and b != a and t.count(".") >= 3:
                edges.setdefault(a, set()).add(b)
    return edges


def private_imports(g) -> list[str]:
    return [
        f"{m} imports {name} from {t}"
        for m, imps in g.items()
        for t, name in imps
        if name is not None and name.startswith("_") and not name.startswith("__") and t.startswith(PACKAGE) and t != m
    ]


def private_attribute_uses(files: dict[str, Path]) -> list[str]:
    """``module._name`` read through a package module bound by an import (``from . import messages``)."""
    known = set(files)
    bad = []
    for m, path in files.items():
        tree = ast.parse(path.read_text())
        bound = {}  # local name -> package module
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _absolute(m, path.name == "__init__.py", node)
                for a in node.names:
                    if f"{target}.{a.name}" in known:
                        bound[a.asname or a.name] = f"{target}.{a.name}"
            elif isinstance(node, ast.Import):
                bound.update({a.asname: a.name for a in node.names if a.asname and a.name in known})
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in bound
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and bound[node.value.id] != m
            ):
                bad.append(f"{m} uses {node.attr} of {bound[node.value.id]}")
    return bad


def forbidden_core_imports(g) -> list[str]:
    """Imports the ROS-free layers may not make: the core none of the list, ``execution`` none but the core."""
    bad = []
    for m, imps in g.items():
        in_core = m == CORE or m.startswith(CORE + ".")
        in_execution = m == EXECUTION or m.startswith(EXECUTION + ".")
        if not (in_core or in_execution):
            continue
        forbidden = FORBIDDEN_IN_CORE + ((EXECUTION,) if in_core else ())
        for t, _ in imps:
            top = t.split(".")[0]
            if t.startswith(forbidden) or top.endswith(MESSAGE_SUFFIXES) or top in ("importlib",):
                bad.append(f"{m} imports {t}")
    return bad


def dynamic_imports(files: dict[str, Path]) -> list[str]:
    bad = []
    for m, p in files.items():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, (ast.Name, ast.Attribute)):
                name = node.func.id if isinstance(node.func, ast.Name) else node.func.attr
                if name in ("import_module", "__import__"):
                    bad.append(f"{m}:{node.lineno} calls {name}")
    return bad


def longest_chain(edges: dict[str, set[str]]) -> list[str]:
    """The longest import chain (the graph is acyclic when this is called)."""
    memo: dict[str, list[str]] = {}

    def chain(n: str) -> list[str]:
        if n not in memo:
            best: list[str] = []
            for m in edges.get(n, ()):
                c = chain(m)
                if len(c) > len(best):
                    best = c
            memo[n] = [n] + best
        return memo[n]

    return max((chain(n) for n in edges), key=len, default=[])


FILES = module_files()
GRAPH = graph(FILES)


def test_the_graph_sees_the_package():
    assert f"{CORE}.methods.table" in FILES and f"{CORE}.time_optimal.solver" in FILES
    assert (f"{CORE}.time_optimal.solver", "plan_time_optimal") in GRAPH[f"{CORE}.methods.time_optimal"]
    assert len(FILES) > 60


def test_no_module_cycle():
    assert find_cycle(module_edges(GRAPH)) is None


def test_no_cycle_between_core_subpackages():
    assert find_cycle(package_edges(GRAPH)) is None


def test_no_private_name_is_imported_across_modules():
    assert private_imports(GRAPH) == []
    assert private_attribute_uses(FILES) == []


def test_the_ros_free_layers_import_no_ros_messages_plots_nodes_or_cli():
    assert forbidden_core_imports(GRAPH) == []


def test_no_dynamic_imports():
    assert dynamic_imports(FILES) == []


def core_edges(g) -> dict[str, set[str]]:
    inside = {m for m in g if m == CORE or m.startswith(CORE + ".")}
    return {m: e & inside for m, e in module_edges(g).items() if m in inside}


def unmapped_modules(files: dict[str, Path], doc: str) -> list[str]:
    """Modules of the core, ``execution`` and the nodes that ``docs/architecture.md`` does not name.

    A module is named as `` `name` ``, ``name.`` (a dotted reference) or ``/name.py``; the command line and the
    plots are described as one module per sub-command or figure and are not listed one by one.
    """
    out = []
    for m, path in files.items():
        layer = m.split(".")[1] if m.count(".") else ""
        if path.stem == "__init__" or layer not in ("core", "execution", "nodes"):
            continue
        name = path.stem
        if f"`{name}`" not in doc and f"`{name}." not in doc and f"/{name}.py" not in doc:
            out.append(m)
    return out


def test_the_map_names_every_module():
    assert unmapped_modules(FILES, (ROOT / "docs" / "architecture.md").read_text()) == []


def test_an_unmapped_module_is_caught(tmp_path):
    files = _fake(tmp_path, {"core/named.py": "", "core/forgotten.py": ""})
    assert unmapped_modules(files, "| `named` | a module |") == [f"{CORE}.forgotten"]


def test_longest_core_import_chain_is_short():
    """Fifteen modules, a package `__init__` included.

    The flat layout had cycles and 15 levels; the subpackages brought it to 14.  A file split by concept
    (the rule of ~400 lines) adds a level where it sits on the longest chain (the method table imports
    every planner): 15 allows that, and a tangle of helpers calling back and forth still fails.
    """
    chain = longest_chain(core_edges(GRAPH))
    assert len(chain) <= 15, " -> ".join(chain)


# ---------------------------------------------------------------- each rule catches a violation
def _fake(tmp_path: Path, sources: dict[str, str]) -> dict[str, Path]:
    for rel, text in sources.items():
        p = tmp_path / PACKAGE / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    for d in [tmp_path / PACKAGE, *(p for p in (tmp_path / PACKAGE).rglob("*") if p.is_dir())]:
        (d / "__init__.py").touch()
    return module_files(tmp_path)


def test_a_cycle_is_caught(tmp_path):
    files = _fake(tmp_path, {"core/a.py": "from .b import x\n", "core/b.py": "def f():\n    from .a import y\n"})
    assert find_cycle(module_edges(graph(files))) is not None


def test_a_subpackage_cycle_is_caught(tmp_path):
    files = _fake(
        tmp_path,
        {"core/p/a.py": "from ..q.b import x\n", "core/q/b.py": "from ..p.c import y\n", "core/p/c.py": "y = 1\n"},
    )
    g = graph(files)
    assert find_cycle(module_edges(g)) is None and find_cycle(package_edges(g)) is not None


def test_a_private_import_is_caught(tmp_path):
    files = _fake(tmp_path, {"core/a.py": "from .b import _hidden\n", "core/b.py": "_hidden = 1\n"})
    assert private_imports(graph(files)) == [f"{CORE}.a imports _hidden from {CORE}.b"]


def test_a_private_name_read_through_an_imported_module_is_caught(tmp_path):
    files = _fake(
        tmp_path,
        {"nodes/a.py": "from . import b\n\nx = b._hidden(1)\n", "nodes/b.py": "def _hidden(v):\n    return v\n"},
    )
    assert private_attribute_uses(files) == [f"{PACKAGE}.nodes.a uses _hidden of {PACKAGE}.nodes.b"]


@pytest.mark.parametrize(
    "line",
    [
        "import rclpy\n",
        "from std_msgs.msg import Float64\n",
        "import matplotlib.pyplot\n",
        "from ..nodes import runner\n",
        "from ..cli.main import entry\n",
        "import importlib\n",
    ],
)
def test_a_forbidden_core_import_is_caught(tmp_path, line):
    files = _fake(tmp_path, {"core/a.py": "def f():\n    " + line})
    assert forbidden_core_imports(graph(files))


def test_execution_may_import_the_core_but_not_ros_and_the_core_not_execution(tmp_path):
    ok = _fake(tmp_path / "ok", {"execution/a.py": "from ..core.b import x\n", "core/b.py": "x = 1\n"})
    assert forbidden_core_imports(graph(ok)) == []
    bad = _fake(tmp_path / "bad", {"execution/a.py": "import rclpy\n", "core/b.py": "from ..execution.a import y\n"})
    assert len(forbidden_core_imports(graph(bad))) == 2


def test_a_dynamic_import_is_caught(tmp_path):
    files = _fake(tmp_path, {"cli/a.py": "m = __import__('os')\n"})
    assert dynamic_imports(files)
