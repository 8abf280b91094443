"""Every third-party package the library imports is declared in pyproject.toml.

A package that is only installed by the test extra (scipy came in through evo) passes every test
of a development install and breaks ``pip install crlam-*.whl``. Imports at a module's top level
must name a distribution of ``[project] dependencies``; an import inside a function or under
``try:`` may name an optional extra's distribution (those paths say which extra to install).
"""

from __future__ import annotations

import ast
import functools
import importlib.metadata
import re
import sys
from pathlib import Path

from crlam.io.structured import load_toml_text

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "python" / "crlam"


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement_names(spec: str) -> set[str]:
    """The distribution a requirement names, and its extras' namesakes (``dask[distributed]``)."""
    match = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[([^\]]*)\])?", spec)
    assert match, spec
    extras = {_normal(e) for e in (match.group(2) or "").split(",") if e.strip()}
    return {_normal(match.group(1))} | extras


#: Subpackages that are an optional feature: they may import their extra's distributions when
#: they load, because nothing outside them imports them when it loads (the CLI imports them in
#: the command's function and names the extra to install when the import fails).
OPTIONAL_SUBPACKAGES = {"ros": "ros"}


def _declared() -> tuple[set[str], set[str]]:
    project = load_toml_text((ROOT / "pyproject.toml").read_text(), "pyproject.toml")["project"]
    required = {n for s in project["dependencies"] for n in _requirement_names(s)}
    optional = {n for specs in project["optional-dependencies"].values() for s in specs for n in _requirement_names(s)}
    return required, optional


def _extra(name: str) -> set[str]:
    project = load_toml_text((ROOT / "pyproject.toml").read_text(), "pyproject.toml")["project"]
    return {n for s in project["optional-dependencies"][name] for n in _requirement_names(s)}


def _type_checking_only(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _top_level_imports(tree: ast.Module) -> set[str]:
    """Root names of the imports that run when the module is imported (not in functions, not under try)."""
    roots: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


def _all_imports(tree: ast.Module) -> set[str]:
    """Root names of every import that can run (imports under ``if TYPE_CHECKING:`` never do)."""
    roots: set[str] = set()
    runnable = ast.Module(body=[n for n in tree.body if not _type_checking_only(n)], type_ignores=[])
    for node in ast.walk(runnable):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


@functools.cache
def _packages_distributions() -> dict[str, list[str]]:
    return dict(importlib.metadata.packages_distributions())


def _distributions(root: str) -> set[str]:
    mapping = _packages_distributions()
    return {_normal(d) for d in mapping.get(root, [root])}


def _third_party(roots: set[str]) -> set[str]:
    return {r for r in roots if r != "crlam" and r not in sys.stdlib_module_names and r != "__future__"}


def test_top_level_imports_are_required_dependencies() -> None:
    required, _ = _declared()
    missing: list[str] = []
    for path in sorted(PKG.rglob("*.py")):
        unit = path.relative_to(PKG).parts[0]
        allowed = required | (_extra(OPTIONAL_SUBPACKAGES[unit]) if unit in OPTIONAL_SUBPACKAGES else set())
        tree = ast.parse(path.read_text(), filename=str(path))
        for root in sorted(_third_party(_top_level_imports(tree))):
            if not _distributions(root) & allowed:
                missing.append(f"{path.relative_to(ROOT)}: {root}")
    assert not missing, "imported when the module loads but not in [project] dependencies:\n" + "\n".join(missing)


def test_every_import_is_declared_somewhere() -> None:
    required, optional = _declared()
    missing: list[str] = []
    for path in sorted(PKG.rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for root in sorted(_third_party(_all_imports(tree))):
            if not _distributions(root) & (required | optional):
                missing.append(f"{path.relative_to(ROOT)}: {root}")
    assert not missing, "imported but declared in no dependency list of pyproject.toml:\n" + "\n".join(missing)


def test_the_rule_catches_an_undeclared_import() -> None:
    tree = ast.parse(
        "import numpy\nfrom scipy.spatial import cKDTree\nif TYPE_CHECKING:\n    import mcap\ndef f():\n    import dask\n"
    )
    assert _third_party(_top_level_imports(tree)) == {"numpy", "scipy"}
    assert _third_party(_all_imports(tree)) == {"numpy", "scipy", "dask"}
    assert _requirement_names("dask[distributed]>=2024.1") == {"dask", "distributed"}


def test_optional_subpackages_are_not_imported_when_crlam_loads() -> None:
    """No module outside an optional subpackage imports it at its top level."""
    offenders: list[str] = []
    for path in sorted(PKG.rglob("*.py")):
        unit = path.relative_to(PKG).parts[0]
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in tree.body:
            names: list[str] = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            for sub in OPTIONAL_SUBPACKAGES:
                if unit != sub and any(n == f"crlam.{sub}" or n.startswith(f"crlam.{sub}.") for n in names):
                    offenders.append(f"{path.relative_to(ROOT)} imports crlam.{sub}")
    assert not offenders, offenders
