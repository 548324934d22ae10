"""The package's layers point down (tests/architecture/imports.py reads every import, inside
functions too, except under ``if TYPE_CHECKING:``); algorithms are built by name through one
registry; ``ceamcl run`` is not an experiment."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from ceamcl.cli import build_parser
from ceamcl.errors import ConfigError
from ceamcl.filters import registry
from ceamcl.maps.worlds import get_world
from tests.architecture.imports import (
    LAYERS,
    SRC,
    cli_only_violations,
    core_violations,
    cycles,
    import_graph,
    layer_of,
    layer_violations,
    loaded_at_run_time,
    module_files,
    unlayered,
)


def test_no_import_cycles() -> None:
    assert cycles(import_graph()) == []


def test_the_core_imports_no_front_end_and_no_rich() -> None:
    assert core_violations() == []


def test_every_module_belongs_to_a_layer() -> None:
    assert unlayered() == []


def test_every_import_points_down_the_layers() -> None:
    assert layer_violations() == []


def test_argparse_and_rich_live_in_the_cli_only() -> None:
    assert cli_only_violations() == []


def test_layer_order() -> None:
    """The order docs/architecture.md describes."""
    assert [name for name, _ in LAYERS] == [
        "base",
        "models",
        "filters and data",
        "runner",
        "outputs",
        "drivers",
        "command line",
    ]
    assert layer_of("ceamcl.io.recorded") < layer_of("ceamcl.runner") < layer_of("ceamcl.io.tum")
    assert layer_of("ceamcl.outputs") < layer_of("ceamcl.replay") < layer_of("ceamcl.cli.run")


def _write(root: Path, module: str, text: str) -> None:
    parts = module.split(".")
    folder = root.joinpath(*parts)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "__init__.py").write_text(text, encoding="utf-8")


def test_the_checker_finds_what_it_looks_for(tmp_path: Path) -> None:
    """A cycle hidden inside a function, a core module importing the CLI and Rich, and a
    module outside the CLI importing argparse are all caught; TYPE_CHECKING imports are not."""
    _write(tmp_path, "ceamcl", "")
    _write(
        tmp_path,
        "ceamcl.maps",
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from ceamcl.experiments import x\n"
        "def f():\n    from ceamcl.cli import main\n    import rich.table\n",
    )
    _write(tmp_path, "ceamcl.cli", "from ceamcl.maps import f\n")
    _write(tmp_path, "ceamcl.experiments", "import argparse\n")
    graph = import_graph(tmp_path)
    assert graph["ceamcl.maps"] == {"ceamcl.cli"}  # not ceamcl.experiments (TYPE_CHECKING)
    assert cycles(graph) == [["ceamcl.cli", "ceamcl.maps"]]
    assert core_violations(tmp_path) == ["ceamcl.maps -> ceamcl.cli", "ceamcl.maps -> rich.table"]
    assert layer_violations(tmp_path) == ["ceamcl.maps (models) -> ceamcl.cli (command line)"]
    assert sorted(cli_only_violations(tmp_path)) == [
        "ceamcl.experiments -> argparse",
        "ceamcl.maps -> rich",
    ]


# ---------------------------------------------------------------------------- the registry
def test_one_function_builds_every_registered_algorithm_by_name() -> None:
    grid = get_world("small-office")
    built = []
    for name in registry.names():
        if registry.unavailable_reason(name) is not None:  # the Nav2 peer without its extra
            continue
        f = registry.make_filter(name, grid, np.random.default_rng(0), n_particles=50)
        assert f.name == name
        for method in ("initialise_global", "initialise_pose", "step", "estimate", "particles"):
            assert callable(getattr(f, method)), (name, method)
        built.append(name)
    assert set(registry.ALGORITHMS) <= set(built)
    # a config of the algorithm's own type is taken as it is; another type is refused
    small = registry.with_config("mcl", n_particles=7)
    f = registry.make_filter("mcl", grid, np.random.default_rng(0), config=small)
    assert f.config == small  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match="mcl takes a MCLConfig"):
        registry.make_filter(
            "mcl", grid, np.random.default_rng(0), config=registry.get("gmcl").default()
        )
    with pytest.raises(ConfigError, match="unknown algorithm 'ekf'; expected one of ceamcl"):
        registry.make_filter("ekf", grid, np.random.default_rng(0))


def test_every_algorithm_module_is_registered() -> None:
    """A filter module that declares ``ALGORITHM`` is listed by the registry (the one line)."""
    declared = set()
    for name, path in module_files().items():
        if not name.startswith(("ceamcl.filters", "ceamcl.peers")):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:
            if isinstance(node, ast.Assign):
                for target in node.targets:
                    if isinstance(target, ast.Name) and target.id.endswith("ALGORITHM"):
                        declared.add((name, target.id))
    assert len(declared) == len(registry.names()), sorted(declared)


def test_every_command_offers_every_registered_algorithm() -> None:
    parser = build_parser()
    for name in registry.names():
        assert parser.parse_args(["demo", "--algorithm", name]).algorithm == name
        assert parser.parse_args(["soak", "--algorithm", name]).algorithm == name
        assert parser.parse_args(["run", "x.log", "--algorithm", name]).algorithm == name
        args = parser.parse_args(["evaluate-log", "x.log", "--algorithms", name])
        assert args.algorithms == [name]


# ---------------------------------------------------------------------------- ceamcl run
def test_ceamcl_run_is_not_an_experiment() -> None:
    graph = import_graph()
    assert "ceamcl.replay" in graph["ceamcl.cli.run"]
    assert not any(m.startswith("ceamcl.experiments") for m in graph["ceamcl.cli.run"])
    # the replay scores convergence with the experiments' measure (pure functions of errors)
    # and uses nothing else of the experiments
    assert {m for m in graph["ceamcl.replay"] if m.startswith("ceamcl.experiments")} <= {
        "ceamcl.experiments.metrics"
    }
    for name, path in module_files().items():
        if name.startswith("ceamcl.experiments"):
            defined = {
                n.name
                for n in ast.parse(path.read_text(encoding="utf-8")).body
                if isinstance(n, ast.FunctionDef)
            }
            assert not defined & {"replay_log", "prepare_log", "obtain_map", "run_summary"}, name
    assert (SRC / "ceamcl" / "replay.py").is_file()


def test_building_the_command_line_imports_no_plotting_library() -> None:
    """docs/architecture.md: matplotlib (0.5-0.7 s) is imported only where a figure is drawn,
    so `ceamcl --help` does not wait for it (`bench --real-maps` imported it at start-up)."""
    code = "from ceamcl.cli import build_parser\nbuild_parser()"
    roots = ("matplotlib", "mpl_toolkits", "dask", "distributed")
    assert loaded_at_run_time(code, roots)[:5] == []
