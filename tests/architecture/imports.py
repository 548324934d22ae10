"""The module import graph of ``ceamcl``, read from source with :mod:`ast`.

Every import statement counts, wherever it stands in a module (inside functions too), except
those under ``if TYPE_CHECKING:``, which never run. ``from ceamcl.x import y`` where ``y`` is a
module of the package counts as an import of ``ceamcl.x.y``; importing ``ceamcl.x.y`` also runs
the packages ``ceamcl`` and ``ceamcl.x``, but a package's ``__init__`` is only counted as a
dependency when it is imported by name (so ``ceamcl.filters.mcl`` does not depend on
everything ``ceamcl.filters`` re-exports).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = "ceamcl"


def module_files(src: Path = SRC) -> dict[str, Path]:
    out: dict[str, Path] = {}
    for path in sorted((src / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _statements(node: ast.AST) -> Iterator[ast.AST]:
    """Every node below ``node`` except the bodies of ``if TYPE_CHECKING:``."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.If) and _is_type_checking(child.test):
            for sub in child.orelse:
                yield sub
                yield from _statements(sub)
            continue
        yield child
        yield from _statements(child)


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The ``ceamcl`` modules that module ``name`` (at ``path``) imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in _statements(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    out.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != PACKAGE:
                continue
            for alias in node.names:
                sub = f"{mod}.{alias.name}"
                out.add(sub if sub in modules else mod)
    return {m for m in out if m in modules and m != name}


def import_graph(src: Path = SRC) -> dict[str, set[str]]:
    modules = module_files(src)
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


#: The core: what a filter needs to run. It knows nothing of the front ends.
CORE = (
    "ceamcl.budget",
    "ceamcl.angles",
    "ceamcl.pose",
    "ceamcl.errors",
    "ceamcl.maps",
    "ceamcl.motion",
    "ceamcl.sensors",
    "ceamcl.filters",
    "ceamcl.simulation",
    "ceamcl.mapping",
)
#: What the core must never import.
FRONT_ENDS = ("ceamcl.experiments", "ceamcl.bench", "ceamcl.viz", "ceamcl.cli", "ceamcl.ros")
FORBIDDEN_THIRD_PARTY = ("rich",)


def _under(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def core_violations(src: Path = SRC) -> list[str]:
    """``module -> imported`` for every import from the core into a front end or Rich."""
    modules = module_files(src)
    out = []
    for name, path in modules.items():
        if not _under(name, CORE):
            continue
        for dep in sorted(imports_of(name, path, modules)):
            if _under(dep, FRONT_ENDS):
                out.append(f"{name} -> {dep}")
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in _statements(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            for n in names:
                if n.split(".")[0] in FORBIDDEN_THIRD_PARTY:
                    out.append(f"{name} -> {n}")
    return out


#: The layers, lowest first. A module may import modules of its own layer or of a lower one,
#: never of a higher one (and never in a cycle). A module belongs to the layer of the longest
#: prefix that names it (``ceamcl.io.results`` is an output, the other ``ceamcl.io`` modules
#: read data). docs/architecture.md draws this.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    (
        "base",
        (
            "ceamcl",
            "ceamcl.angles",
            "ceamcl.pose",
            "ceamcl.errors",
            "ceamcl.budget",
            # file reading that knows nothing of robots: bounded streams, safe YAML
            "ceamcl.io.streams",
            "ceamcl.io.safe_yaml",
            "ceamcl.io.created",
        ),
    ),
    ("models", ("ceamcl.maps", "ceamcl.motion", "ceamcl.sensors")),
    (
        "filters and data",
        (
            "ceamcl.filters",
            "ceamcl.peers",
            "ceamcl.simulation",
            "ceamcl.mapping",
            "ceamcl.io",
            "ceamcl.checks",
        ),
    ),
    ("runner", ("ceamcl.runner", "ceamcl.warmup")),
    (
        "outputs",
        (
            "ceamcl.outputs",
            "ceamcl.viz",
            "ceamcl.io.results",
            "ceamcl.io.tum",
            "ceamcl.io.mcap_export",
        ),
    ),
    (
        "drivers",
        (
            "ceamcl.replay",
            "ceamcl.demo",
            "ceamcl.soak",
            "ceamcl.experiments",
            "ceamcl.bench",
            "ceamcl.ros",  # the ROS 2 node: a driver like replay, fed by ROS topics
        ),
    ),
    ("command line", ("ceamcl.cli", "ceamcl.__main__", "ceamcl.ros.__main__")),
)
#: Third-party modules only the command line may import: argument parsing and the terminal.
CLI_ONLY_THIRD_PARTY = ("argparse", "rich")


def layer_of(name: str) -> int:
    """The index in :data:`LAYERS` of module ``name`` (longest matching prefix; the package
    ``ceamcl`` itself names only its ``__init__``)."""
    best, best_len = -1, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            matches = name == p or (p != PACKAGE and name.startswith(p + "."))
            if matches and len(p) > best_len:
                best, best_len = i, len(p)
    if best < 0:
        raise KeyError(f"{name} is in no layer of tests/architecture/imports.py")
    return best


def unlayered(src: Path = SRC) -> list[str]:
    """Modules no prefix of :data:`LAYERS` names."""
    out = []
    for name in module_files(src):
        try:
            layer_of(name)
        except KeyError:
            out.append(name)
    return out


def layer_violations(src: Path = SRC) -> list[str]:
    """``module (layer) -> imported (higher layer)`` for every import that points up."""
    graph = import_graph(src)
    out = []
    for name in sorted(graph):
        mine = layer_of(name)
        for dep in sorted(graph[name]):
            theirs = layer_of(dep)
            if theirs > mine:
                out.append(f"{name} ({LAYERS[mine][0]}) -> {dep} ({LAYERS[theirs][0]})")
    return out


def third_party_imports(path: Path) -> set[str]:
    """Top-level names of the non-``ceamcl`` modules a file imports (outside TYPE_CHECKING)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: set[str] = set()
    for node in _statements(tree):
        if isinstance(node, ast.Import):
            out.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module.split(".")[0])
    out.discard(PACKAGE)
    return out


def cli_only_violations(src: Path = SRC) -> list[str]:
    """``module -> argparse/rich`` for every module outside ``ceamcl.cli`` that imports them."""
    out = []
    for name, path in module_files(src).items():
        if _under(name, ("ceamcl.cli",)):
            continue
        for dep in sorted(third_party_imports(path) & set(CLI_ONLY_THIRD_PARTY)):
            out.append(f"{name} -> {dep}")
    return out


if __name__ == "__main__":
    g = import_graph()
    for c in cycles(g):
        print("cycle:", " <-> ".join(c))
    for v in core_violations():
        print("core violation:", v)
    for name in unlayered():
        print("in no layer:", name)
    for v in layer_violations():
        print("points up:", v)
    for v in cli_only_violations():
        print("outside the CLI:", v)


def loaded_at_run_time(code: str, roots: tuple[str, ...]) -> list[str]:
    """The modules under ``roots`` that running ``code`` in a fresh interpreter imports (the
    static graph above cannot see what third-party packages pull in)."""
    import json
    import subprocess
    import sys

    probe = (
        f"{code}\nimport json, sys\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {roots!r})))\n"
    )
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return list(json.loads(run.stdout.strip().splitlines()[-1]))
