"""The module graph of the Rust core (crates/crlam-core/src) has no import loops and respects the
layer order grid -> raycast -> sensor -> crm -> rbpf -> info -> planner.

Every file is a node (``crm/map.rs`` is ``crm::map``, ``crm/mod.rs`` is ``crm``). A reference to an
item is an edge to the file that defines it: ``use`` declarations and ``crate::``, ``super::`` and
``self::`` paths in code are followed through the ``pub use`` re-exports of parent modules, so
``crate::crm::CrmMap`` is an edge to ``crm::map``. A parent's ``pub use`` of its own children (its
public face) is not an edge; comments, strings and ``#[cfg(test)] mod`` blocks are not read.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "crates" / "crlam-core" / "src"

# Top-level modules from the ground floor up. A module may use modules of lower layers and the
# other files of its own top-level module, never a module of its own layer or of a higher one.
LAYERS: list[set[str]] = [
    {"error", "simd", "rng"},
    # pose draws poses from a covariance (rng) and checks it (error).
    {"limits", "numeric", "pose"},
    {"grid", "motion", "resample"},
    {"raycast"},
    {"sensor", "ogm", "sim"},
    {"crm"},
    {"rbpf"},
    # mcl moves its particles with rbpf's odometry tracker and update triggers.
    {"info", "mcl"},
    {"planner"},
]

Module = tuple[str, ...]

_TOKENS = re.compile(
    r"""//[^\n]*                      # line comment (doc comments too)
      | /\*                           # block comment (nesting handled below)
      | r(\#*)"                       # raw string
      | b?"(?:\\.|[^"\\])*"           # string
      | b?'(?:\\.|[^\\'])'            # char (a lifetime 'a has no closing quote)
    """,
    re.X | re.S,
)


def _strip(text: str) -> str:
    """The code without comments, strings and char literals (each replaced by a space)."""
    out: list[str] = []
    pos = 0
    while (m := _TOKENS.search(text, pos)) is not None:
        out.append(text[pos : m.start()])
        tok = m.group(0)
        if tok.startswith("/*"):
            depth, i = 1, m.end()
            while depth and i < len(text):
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
            pos = i
        elif tok.startswith("r"):
            end = text.index('"' + m.group(1), m.end())
            pos = end + 1 + len(m.group(1))
        else:
            pos = m.end()
        out.append(" ")
    out.append(text[pos:])
    return "".join(out)


def _drop_test_modules(code: str) -> str:
    """``code`` without its ``#[cfg(test)] mod name { ... }`` blocks."""
    while (m := re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{", code)) is not None:
        depth, i = 1, m.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(code[i], 0)
            i += 1
        code = code[: m.start()] + code[i:]
    return code


def _split_top(s: str) -> list[str]:
    """``s`` split at the commas outside braces."""
    parts, depth, cur = [], 0, ""
    for ch in s:
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        depth += {"{": 1, "}": -1}.get(ch, 0)
        cur += ch
    parts.append(cur)
    return [p.strip() for p in parts if p.strip()]


def _expand(tree: str, prefix: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], str]]:
    """The leaves of a use tree as (path, name bound): ``a::{b, c::d as e}`` gives
    ``(a, b), b`` and ``(a, c, d), e``."""
    tree = re.sub(r"\s+", " ", tree).strip()
    if "{" in tree:
        head, _, rest = tree.partition("{")
        segs = tuple(s for s in head.strip().rstrip(":").split("::") if s)
        leaves = []
        for part in _split_top(rest[: rest.rindex("}")]):
            leaves += _expand(part, prefix + segs)
        return leaves
    path, _, alias = tree.partition(" as ")
    segs = tuple(s.strip() for s in path.split("::") if s.strip())
    if segs and segs[-1] == "self":
        segs = segs[:-1]
    full = prefix + segs
    return [(full, alias.strip() or (full[-1] if full else ""))]


class Crate:
    """The files of the crate, their references and the re-exports of each module."""

    def __init__(self, files: dict[Module, str]) -> None:
        self.code = {mod: _drop_test_modules(_strip(text)) for mod, text in files.items()}
        # (is pub, path, name bound) of every use declaration of each module.
        self.uses: dict[Module, list[tuple[bool, tuple[str, ...], str]]] = {}
        self.inline: dict[Module, list[tuple[str, ...]]] = {}
        use_decl = re.compile(r"(?<![\w:])(pub(?:\s*\([^)]*\))?\s+)?use\s+([^;]+);")
        for mod, code in self.code.items():
            self.uses[mod] = [
                (m.group(1) is not None, path, name) for m in use_decl.finditer(code) for path, name in _expand(m.group(2))
            ]
            rest = use_decl.sub(" ", code)
            roots = ["\\$?crate", "super", "self"] + [re.escape(c[-1]) for c in self.code if c and c[:-1] == mod]
            inline = re.compile(rf"(?<![\w:$])((?:{'|'.join(roots)})(?:\s*::\s*\w+)+)")
            self.inline[mod] = [tuple(s.strip() for s in m.group(1).split("::")) for m in inline.finditer(rest)]

    @classmethod
    def read(cls, src: Path) -> Crate:
        files: dict[Module, str] = {}
        for path in sorted(src.rglob("*.rs")):
            parts = path.relative_to(src).with_suffix("").parts
            if parts[-1] == "mod":
                parts = parts[:-1]
            if parts == ("lib",):
                parts = ()
            files[parts] = path.read_text(encoding="utf-8")
        return cls(files)

    def start(self, mod: Module, path: tuple[str, ...]) -> tuple[Module, tuple[str, ...]] | None:
        """The module a path starts from and the rest of it; None for an external crate."""
        if not path:
            return None
        head, rest = path[0], path[1:]
        if head in ("crate", "$crate"):
            return (), rest
        if head == "self":
            return mod, rest
        if head == "super":
            base = mod[:-1]
            while rest and rest[0] == "super":
                base, rest = base[:-1], rest[1:]
            return base, rest
        if mod + (head,) in self.code:
            return mod + (head,), rest
        return None

    def resolve(self, mod: Module, path: tuple[str, ...], depth: int = 0) -> Module | None:
        """The file that defines what ``path`` (written in ``mod``) names."""
        started = self.start(mod, path)
        if started is None or depth > 20:
            return None
        base, rest = started
        while rest and base + (rest[0],) in self.code:
            base, rest = base + (rest[0],), rest[1:]
        if rest and rest[0] != "*":
            for is_pub, p, name in self.uses[base]:
                if is_pub and name == rest[0]:
                    return self.resolve(base, p, depth + 1) or base
        return base

    def edges(self) -> dict[Module, set[Module]]:
        graph: dict[Module, set[Module]] = {m: set() for m in self.code}
        for mod in self.code:
            refs = [(is_pub, p) for is_pub, p, _ in self.uses[mod]] + [(False, p) for p in self.inline[mod]]
            for is_pub, path in refs:
                target = self.resolve(mod, path)
                if target is None or target == mod:
                    continue
                if is_pub and target[: len(mod)] == mod:
                    continue  # a parent's public face: re-exports of its own children
                graph[mod].add(target)
        return graph


def _cycles(graph: dict[Module, set[Module]]) -> list[list[Module]]:
    """The strongly connected components with more than one node (Tarjan)."""
    index: dict[Module, int] = {}
    low: dict[Module, int] = {}
    stack: list[Module] = []
    on_stack: set[Module] = set()
    found: list[list[Module]] = []

    def visit(v: Module) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _name(m: Module) -> str:
    return "::".join(m) or "crate"


@pytest.fixture(scope="module")
def graph() -> dict[Module, set[Module]]:
    return Crate.read(SRC).edges()


def test_the_module_graph_of_the_core_has_no_import_loops(graph: dict[Module, set[Module]]) -> None:
    loops = [
        " <-> ".join(_name(m) for m in comp)
        + ": "
        + "; ".join(f"{_name(a)} -> {_name(b)}" for a in comp for b in sorted(graph[a]) if b in comp)
        for comp in _cycles(graph)
    ]
    assert not loops, "import loops:\n" + "\n".join(loops)


def test_every_top_level_module_uses_only_lower_layers(graph: dict[Module, set[Module]]) -> None:
    rank = {name: i for i, layer in enumerate(LAYERS) for name in layer}
    tops = {m[0] for m in graph if m}
    assert tops == set(rank), f"modules missing from LAYERS or gone: {sorted(tops ^ set(rank))}"
    wrong = [
        f"{_name(a)} -> {_name(b)}"
        for a, targets in graph.items()
        for b in sorted(targets)
        if a and b and a[0] != b[0] and rank[b[0]] >= rank[a[0]]
    ]
    assert not wrong, "uses of a module of the same or a higher layer:\n" + "\n".join(wrong)


def test_the_checker_sees_edges_through_re_exports_and_inline_paths() -> None:
    """The reader finds what it must: a ``pub use`` chain, a ``super::`` path in code and a use
    tree, on a crate written here."""
    crate = Crate(
        {
            (): "pub mod a; pub mod b; pub use a::thing::Thing;",
            ("a",): "mod thing; pub use thing::Thing; // use crate::b::Never;",
            ("a", "thing"): 'pub struct Thing; fn f() { super::super::b::go(); let s = "crate::b::Never"; }',
            ("b",): "use crate::{a::{self}, Thing as T}; #[cfg(test)] mod tests { use crate::a::thing; } pub fn go() {}",
        }
    )
    g = crate.edges()
    assert g[("b",)] == {("a",), ("a", "thing")}
    assert g[("a", "thing")] == {("b",)}
    assert g[("a",)] == set() and g[()] == set()
    assert _cycles(g) == [[("a", "thing"), ("b",)]]


def test_the_glue_crate_has_no_import_loops() -> None:
    """The PyO3 glue (crates/crlam-py/src) is one layer of flat modules; among them no loops
    (the ``dispatch!`` macro's paths count: ``Func`` lives in dispatch.rs beside it)."""
    glue = Crate.read(SRC.parents[1] / "crlam-py" / "src").edges()
    loops = [" <-> ".join(_name(m) for m in comp) for comp in _cycles(glue)]
    assert not loops, "import loops:\n" + "\n".join(loops)
    assert ("info",) in glue[("planner",)] and ("dispatch",) in glue[("info",)]  # the reader sees the glue's uses
