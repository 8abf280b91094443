"""The module graph of the Python package (python/crlam) has no import loops and respects the
layer order of :data:`LAYERS` between its units and of :data:`PACKAGE_LAYERS` inside each
subpackage (the Rust core's is checked by test_rust_modules.py).

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
    # process_memory: the process's peak memory and malloc_trim, standard library only.
    {"limits", "pose", "process_memory"},
    {"crlam"},  # the package's __init__: its version and the errors and limits it re-exports
    # io's run folders record the version in their markers.
    # live_view serves ROS messages' bytes on a Foxglove WebSocket: it reads no crlam module.
    {"io", "live_view"},
    # What a run learns from a log before its filter runs (body beams, laser mount, map reach,
    # re-timed odometry); the maps and the simulator read and write through io.
    {"preflight", "mapping", "sim"},
    {"info"},
    {"planner"},
    # The filters over the maps: slam (SlamConfig reads its map reach through preflight) and
    # localization in a known map.
    {"slam", "localize"},
    # eval gives skipped scans their poses by slam's fill rule.
    {"eval"},
    {"viz"},
    {"experiments"},
    # The live ROS 2 nodes run the experiments' SLAM runner and explorer.
    {"ros"},
    # The benchmarks run the experiments' SLAM runner and the ROS 2 nodes.
    {"bench"},
    {"cli"},
    {"__main__"},
]

# The modules of each subpackage from its ground floor up, by LAYERS' rule inside the package
# (a subpackage of a subpackage, such as slam's presets, is one module here). Not listed: the
# package's ``__init__``, its face, which may import any of its modules, and a ``__main__``, its
# entry point above the face; no module of the package imports either (they import each other
# by name, so the face cannot close a loop).
PACKAGE_LAYERS: dict[str, list[set[str]]] = {
    "io": [
        # Record types, line and TOML reading, the dataset registry, run folders, bag topics.
        {
            "carmen_types",
            "datasets",
            "known_pose_scan",
            "lines",
            "message_checks",
            "npz_check",
            "readings",
            "rosbag_topics",
            "rosbag_writer",
            "run_folder",
            "structured",
        },
        {"bag_open", "belief", "carmen_writer", "fetch", "nav2", "relations", "rosbag_scans", "rosbag_tf", "tum"},
        {"carmen", "rosbag"},  # the two log formats
        {"logs"},  # either log, by its file
        {"convert"},
    ],
    "preflight": [
        {"body_mask", "laser_mount", "map_range", "odometry_retime"},
        {"lidar_check"},  # body beams and the mount, checked on a log's first scans
    ],
    "sim": [
        {"grid_ops", "odometry", "raycast", "shapes"},
        {"layout", "world"},
        {"lookalike", "planning", "sensor", "worlds"},
        {"robot"},
        {"simulate"},
    ],
    "info": [
        {"functions", "prior"},
        {"surface"},
    ],
    "slam": [
        # Pose maths, the log-fitted odometry noise, the preset files read as a given class's
        # fields, the saved run a new one continues, and the pose graph of loop closing.
        {"fill", "grid_alignment", "loop_closing", "motion_noise", "preset_files", "prior"},
        {"config"},
        {"presets", "run", "scan_odometry"},
        {"time_offset"},  # estimated with scan-matching odometry
    ],
    "localize": [
        {"map"},
        {"run"},
    ],
    "eval": [
        {"align", "likelihood_bias", "maps", "odometry_travel"},
        {"trajectory"},
    ],
    "viz": [
        {"palette"},
        {"maps"},
        {"explore", "iig", "info", "localization", "trajectories"},
    ],
    "experiments": [
        # Executors, progress and resume bookkeeping, and the pieces the runs are made of.
        {
            "executor",
            "explore_candidates",
            "explore_window",
            "progress",
            "resume",
            "simulate",
            "slam_mcap",
            "stress_variants",
        },
        {"explore_live_view", "map_outputs", "pool", "semireal"},
        {"explore", "iig", "remote_run", "slam_live_view", "slam_outputs"},
        {"dask_executor", "explore_sweep", "iig_demo", "slam_run"},  # slam_run: one crlam slam run
        {"known_poses", "localize_run", "localize_trials", "sweep"},
        {"localization", "real_logs", "stress", "table1"},  # the papers' and the project's experiments
        {"demo"},
    ],
    "ros": [
        {"dds", "explore_goal", "messages", "odometry_buffer", "params", "qos"},
        {"message_helpers", "services"},
        {"live_view_mirror", "save_map_service"},
        {"slam_node"},
        {"explore_node", "localize_node", "play"},  # the nodes built on the SLAM node
        {"bench", "reference"},
    ],
    "bench": [
        {"slam"},  # whole crlam slam runs
        {"suite"},  # the micro-benchmarks, and the SLAM figures among them
    ],
    "cli": [
        {"conventions", "failures"},
        {"data", "live", "options"},
        # One module per command.
        {
            "bench",
            "convert",
            "demo",
            "diagnose",
            "eval",
            "executor",
            "explore",
            "info",
            "localize",
            "map",
            "ros",
            "semireal",
            "simulate",
            "slam",
        },
        {"experiment"},  # runs the experiments through the executor's flags
    ],
}

#: The modules of a package that PACKAGE_LAYERS leaves out: its face and its entry point.
FACE = "__init__"
ENTRY = "__main__"

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


def _packages() -> set[str]:
    """The subpackages of crlam (the units that are folders)."""
    return {_unit(m) for m in _modules() if (PKG / _unit(m)).is_dir()}


def _member(module: Module) -> str:
    """The module's name inside its subpackage (``crlam.slam.presets.x`` is ``presets``; the
    package itself is its ``__init__``)."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 else FACE


def _package_layer_of(package: str) -> dict[str, int]:
    return {member: i for i, layer in enumerate(PACKAGE_LAYERS[package]) for member in layer}


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


def test_every_package_module_has_a_layer() -> None:
    assert set(PACKAGE_LAYERS) == _packages(), f"packages: {sorted(_packages())}; in PACKAGE_LAYERS: {sorted(PACKAGE_LAYERS)}"
    for package, layers in PACKAGE_LAYERS.items():
        members = {_member(m) for m in _modules() if _unit(m) == package} - {FACE, ENTRY}
        named = set().union(*layers)
        assert members == named, f"{package}: not in PACKAGE_LAYERS: {sorted(members - named)}; gone: {sorted(named - members)}"
        assert sum(len(layer) for layer in layers) == len(named), f"{package}: a module in two layers"


def test_imports_inside_a_package_point_down_its_layers() -> None:
    wrong = []
    for a, edges in sorted(_graph().items()):
        package = _unit(a)
        if package not in PACKAGE_LAYERS or _member(a) in (FACE, ENTRY):
            continue
        layer = _package_layer_of(package)
        for b in sorted(edges):
            if _unit(b) != package or (a, b) in KNOWN_UPWARD:
                continue
            if _member(b) in (FACE, ENTRY):
                wrong.append(f"{a} imports its own package's {_member(b)} ({b}): import the module that defines the name")
            elif _member(b) == _member(a) or not {_member(a), _member(b)} <= layer.keys():
                continue  # inside one module (a subpackage's files), or unlisted: see the test above
            elif layer[_member(b)] >= layer[_member(a)]:
                wrong.append(f"{a} (layer {layer[_member(a)]} of {package}) imports {b} (layer {layer[_member(b)]})")
    assert not wrong, "\n".join(wrong)


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
        ("from crlam.slam.config import SlamConfig\n", {"crlam.slam.config"}),
        ("from crlam.slam.presets import resolve\n", {"crlam.slam.presets"}),
    ],
)
def test_the_graph_sees_every_kind_of_import(source: str, edges: set[str]) -> None:
    """Deferred, type-only and relative imports are edges (here as if written in crlam/info/functions.py)."""
    modules = _modules()
    names = _imported_names("crlam.info.functions", PKG / "info" / "functions.py", ast.parse(source))
    assert {_resolve(n, modules) for n in names} - {None} == edges
