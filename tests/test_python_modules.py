"""The module graph of the Python package (python/crlam) has no import loops and respects the
layer order of :data:`LAYERS` (the Rust core's is checked by test_rust_modules.py).

Every file is a node (``crlam/info/surface.py`` is ``crlam.info.surface``, a package's
``__init__.py`` is the package). Every ``import`` and ``from ... import`` of ``crlam`` anywhere in
a file is an edge, also inside functions and under ``if TYPE_CHECKING:`` (a deferred or type-only
import is still a dependency: it only hides the loop from the interpreter). ``from crlam.x import
y`` is an edge to ``crlam.x.y`` when that is a module, else to ``crlam.x`` (relative imports alike).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "python" / "crlam"

# Units (top-level modules and subpackages of crlam) from the ground floor up. A file may import
# the files of its own unit and the units of lower layers, never a unit of its own layer or of a
# higher one: the library below the figures (viz), the figures below the experiments, the
# command line on top.
LAYERS: list[set[str]] = [
    {"errors", "_native"},
    {"limits", "pose"},
    {"crlam"},  # the package's __init__: its version and the errors and limits it re-exports
    # run_folder records the version in each run folder's markers.
    # live_view serves ROS messages' bytes on a Foxglove WebSocket: it reads no crlam module.
    {"io", "run_folder", "live_view"},
    # Reading checks and the odometry's re-attachment at corrected stamps: below the maps and slam.
    {"body_mask", "laser_mount", "odometry_retime", "map_range"},
    # Maps and the simulator read and write through io; fill and grid_alignment are pose maths.
    # preset_files reads the preset TOML files as the fields of a class it is given (SlamConfig).
    {"mapping", "sim", "fill", "grid_alignment", "motion_noise", "preset_files"},
    {"slam_continue", "localize_map", "info"},
    # SlamConfig reads its presets through preset_files, passing its own class.
    {"slam_config", "planner"},
    # The presets bind preset_files to SlamConfig; slam runs the filter a SlamConfig describes.
    {"presets", "slam"},
    {"scan_odometry", "localize", "eval"},
    # The log's pre-passes: the time offset reads scan-matching odometry; the lidar check the mount.
    {"time_offset", "lidar_check"},
    {"viz"},
    {"experiments"},
    # The live ROS 2 nodes run the experiments' SLAM runner and explorer.
    {"ros"},
    # The SLAM benchmark runs the experiments' SLAM runner; bench runs it among the others.
    {"bench_slam"},
    {"bench"},
    {"cli"},
    {"__main__"},
]

#: Loops and upward edges that are known and not yet untied: (importer, imported) files. Each
#: must still exist (test_the_known_exceptions_still_exist), so the list cannot go stale.
KNOWN_UPWARD: set[tuple[str, str]] = set()

Module = str


def _modules() -> dict[Module, Path]:
    out: dict[Module, Path] = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    out["crlam._native"] = PKG / "_native.pyi"  # the compiled extension (its stub stands for it)
    return out


def _imported_names(module: Module, path: Path, tree: ast.AST) -> Iterator[str]:
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            yield from (f"{source}.{a.name}" for a in node.names)


def _resolve(name: str, modules: dict[Module, Path]) -> Module | None:
    """The module an imported name is (or is defined in): the longest module prefix of it."""
    if not name.startswith("crlam"):
        return None
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _graph() -> dict[Module, set[Module]]:
    modules = _modules()
    graph: dict[Module, set[Module]] = {}
    for module, path in modules.items():
        if path.suffix != ".py":
            graph[module] = set()
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        graph[module] = {m for m in (_resolve(n, modules) for n in _imported_names(module, path, tree)) if m and m != module}
    return graph


def _unit(module: Module) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "crlam"


def _layer_of() -> dict[str, int]:
    return {unit: i for i, layer in enumerate(LAYERS) for unit in layer}


def _loops(graph: dict[Module, set[Module]]) -> list[list[Module]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[Module, int] = {}
    low: dict[Module, int] = {}
    stack: list[Module] = []
    on_stack: set[Module] = set()
    out: list[list[Module]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        out.append(sorted(component))
    return out


def test_every_unit_has_a_layer() -> None:
    units = {_unit(m) for m in _modules()}
    named = set().union(*LAYERS)
    assert units == named, f"not in LAYERS: {sorted(units - named)}; in LAYERS but gone: {sorted(named - units)}"


def test_the_package_has_no_import_loops() -> None:
    graph = _graph()
    for a, b in KNOWN_UPWARD:
        graph[a].discard(b)
    loops = _loops(graph)
    assert not loops, "\n".join(" <-> ".join(loop) for loop in loops)


def test_imports_point_down_the_layers() -> None:
    layer = _layer_of()
    upward = [
        f"{a} (layer {layer[_unit(a)]}) imports {b} (layer {layer[_unit(b)]})"
        for a, edges in sorted(_graph().items())
        for b in sorted(edges)
        if _unit(a) != _unit(b) and layer[_unit(b)] >= layer[_unit(a)] and (a, b) not in KNOWN_UPWARD
    ]
    assert not upward, "\n".join(upward)


def test_the_known_exceptions_still_exist() -> None:
    graph = _graph()
    gone = sorted(edge for edge in KNOWN_UPWARD if edge[1] not in graph[edge[0]])
    assert not gone, f"untied: remove {gone} from KNOWN_UPWARD"


@pytest.mark.parametrize(
    ("source", "edges"),
    [
        ("from crlam.viz.maps import save_figure\n", {"crlam.viz.maps"}),
        ("from crlam.info import make_function\n", {"crlam.info"}),
        ("def f():\n    from crlam.experiments.explore import ExploreRun\n", {"crlam.experiments.explore"}),
        ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from crlam.slam import SlamConfig\n", {"crlam.slam"}),
        ("from . import surface\n", {"crlam.info.surface"}),
        ("from crlam.info import surface, make_function\n", {"crlam.info.surface", "crlam.info"}),
        ("from .prior import MapPrior\n", {"crlam.info.prior"}),
        ("import crlam.io.tum\n", {"crlam.io.tum"}),
        ("from crlam import _native\n", {"crlam._native"}),
    ],
)
def test_the_graph_sees_every_kind_of_import(source: str, edges: set[str]) -> None:
    """Deferred, type-only and relative imports are edges (here as if written in crlam/info/functions.py)."""
    modules = _modules()
    names = _imported_names("crlam.info.functions", PKG / "info" / "functions.py", ast.parse(source))
    assert {_resolve(n, modules) for n in names} - {None} == edges
