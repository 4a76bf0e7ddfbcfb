"""The house rules of DESIGN.md, checked on the source: no two modules import each other,
imports point down the layers, no module over 600 lines.

Every module of src/vei is parsed with ast; its imports are collected wherever they stand
(module level, inside functions, under ``if TYPE_CHECKING``), relative ones resolved, and
``from package import name`` counted as an import of the submodule when ``name`` is one.
Each test lists every violation in its message.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "vei"
MAX_LINES = 600


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    """Dotted name -> file of every module of the package (caches and data excluded)."""
    return {
        _module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if "__pycache__" not in p.parts
    }


def _is_type_checking(node: ast.AST) -> bool:
    """``if TYPE_CHECKING:`` / ``if typing.TYPE_CHECKING:``."""
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(
    name: str, path: Path, known: dict[str, Path], *, runtime_only: bool = False
) -> set[str]:
    """The vei modules ``name`` imports (anywhere in the file), resolved to known modules;
    with ``runtime_only`` those under ``if TYPE_CHECKING:`` are left out."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    type_only = {
        id(n)
        for block in ast.walk(tree)
        if _is_type_checking(block)
        for stmt in block.body
        for n in ast.walk(stmt)
    }

    def add(target: str) -> None:
        # the longest known prefix: 'vei.sim.engine.step' -> 'vei.sim.engine'
        parts = target.split(".")
        for k in range(len(parts), 0, -1):
            cand = ".".join(parts[:k])
            if cand in known:
                if cand != name:
                    found.add(cand)
                return

    for node in ast.walk(tree):
        if runtime_only and id(node) in type_only:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "vei" or alias.name.startswith("vei."):
                    add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not (mod == "vei" or mod.startswith("vei.")):
                continue
            for alias in node.names:
                sub = f"{mod}.{alias.name}"
                add(sub if sub in known else mod)
    return found


def import_graph(*, runtime_only: bool = False) -> dict[str, set[str]]:
    """Module -> the vei modules it imports (``runtime_only``: not under TYPE_CHECKING)."""
    known = _modules()
    return {
        name: _imports(name, path, known, runtime_only=runtime_only) for name, path in known.items()
    }


def test_the_import_graph_is_read():
    """Guards the checks below against reading nothing: edges the code is known to have."""
    graph = import_graph()
    assert len(graph) > 50
    assert "vei.errors" in graph["vei.cli.main"]
    assert "vei.io.atomic" in graph["vei.catalogue.store"]
    # a function-level import counts too (run.py imports the pool inside executor())
    assert "vei.sweep.workers" in graph["vei.catalogue.run"]


def test_no_two_modules_import_each_other():
    """Type-only imports (under TYPE_CHECKING) count too; the message marks the pairs that
    would not import each other at run time."""
    graph, runtime = import_graph(), import_graph(runtime_only=True)
    pairs = sorted(
        (a, b) for a, targets in graph.items() for b in targets if a < b and a in graph.get(b, ())
    )

    def note(a: str, b: str) -> str:
        both = b in runtime[a] and a in runtime[b]
        return "" if both else " (one side only under TYPE_CHECKING)"

    assert not pairs, f"{len(pairs)} pair(s) of modules import each other:\n" + "\n".join(
        f"  {a} <-> {b}{note(a, b)}" for a, b in pairs
    )


def _is_config(module: str) -> bool:
    return module == "vei.config" or module.startswith("vei.config.")


def test_config_imports_nothing_above_it():
    """DESIGN.md layering: the configuration (vei.config*) imports no vei module but
    vei.errors, vei.types and other vei.config* modules (anywhere in the file, inside
    functions and under TYPE_CHECKING too)."""
    graph = import_graph()
    configs = [m for m in graph if _is_config(m)]
    assert "vei.config.perception" in graph["vei.config"]  # guard: edges are read
    upward = sorted(
        (a, b)
        for a in configs
        for b in graph[a]
        if not (_is_config(b) or b in ("vei.errors", "vei.types"))
    )
    assert not upward, f"{len(upward)} upward import(s) of the config layer:\n" + "\n".join(
        f"  {a} -> {b}" for a, b in upward
    )


def _in(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


#: DESIGN.md's direction rules: (who, what it must never import, why).
FORBIDDEN: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("vei.metrics", ("vei.models", "vei.sim", "vei.experiments"), "metrics score any backend"),
    ("vei.models", ("vei.sim", "vei.metrics", "vei.experiments"), "models never know the engine"),
    ("vei.export", ("vei.sim",), "export knows no backend"),
    # issue 33: the studies sit above the sweep, the sweep above the engine
    ("vei.sim", ("vei.sweep", "vei.experiments", "vei.risk", "vei.catalogue", "vei.gym"),
     "the engine knows no study"),
    ("vei.sweep", ("vei.experiments", "vei.risk", "vei.catalogue", "vei.gym"),
     "sweeps sit below the studies"),
    ("vei.experiments", ("vei.risk", "vei.catalogue", "vei.gym"), "experiments sit below risk"),
    ("vei.risk", ("vei.experiments", "vei.catalogue", "vei.gym"),
     "risk uses the sweep and the engine, not the paper's experiments"),
)  # fmt: skip

#: The bottom floor (DESIGN.md: box geometry, types, errors, atomic writes): imports no vei
#: module but vei.errors and vei.types.
BOTTOM_FLOOR = ("vei.boxes", "vei.types", "vei.errors", "vei.io.atomic")


def _direction_violations(graph: dict[str, set[str]]) -> list[str]:
    """Every edge of ``graph`` against DESIGN.md's direction rules, as readable lines."""
    bad: list[str] = []
    for who, never, why in FORBIDDEN:
        bad += [
            f"  {a} -> {b} ({who} never imports {n}: {why})"
            for a in sorted(graph)
            if _in(a, who)
            for b in sorted(graph[a])
            for n in never
            if _in(b, n)
        ]
    bad += [
        f"  {a} -> {b} (nothing below vei.cli imports it)"
        for a in sorted(graph)
        if not _in(a, "vei.cli")
        for b in sorted(graph[a])
        if _in(b, "vei.cli")
    ]
    bad += [
        f"  {a} -> {b} (the bottom floor imports only vei.errors / vei.types)"
        for a in BOTTOM_FLOOR
        for b in sorted(graph.get(a, ()))
        if b not in ("vei.errors", "vei.types")
    ]
    return bad


def test_imports_point_down_the_layers():
    """DESIGN.md: metrics never import models/sim/experiments; models never sim/metrics/
    experiments; export never sim; the engine (vei.sim) no sweep or study, the sweep no
    study (experiments, risk, catalogue, gym), experiments and risk not each other or
    the catalogue / gym; nothing below vei.cli imports vei.cli; the bottom floor
    (vei.boxes, vei.types, vei.errors, vei.io.atomic) imports nothing of vei but
    vei.errors/vei.types.
    Imports anywhere in a file count (inside functions and under TYPE_CHECKING too)."""
    graph = import_graph()
    assert all(m in graph for m in BOTTOM_FLOOR)  # guard: the floor exists
    assert "vei.boxes" in graph["vei.metrics._trace"]  # guard: edges are read
    bad = _direction_violations(graph)
    assert not bad, f"{len(bad)} import(s) against DESIGN.md's direction:\n" + "\n".join(bad)


def test_direction_rules_catch_each_kind_of_violation():
    """Hand-made graph with one violation of each rule (and allowed edges around them)."""
    graph = {
        "vei.metrics.ttc": {"vei.boxes", "vei.models.geometry", "vei.metrics.geometry"},
        "vei.models.sfm": {"vei.boxes", "vei.sim.engine"},
        "vei.export.openscenario": {"vei.io.atomic", "vei.sim"},
        "vei.sweep.run": {"vei.sim.engine", "vei.cli.main"},
        "vei.sweep.riskmap": {"vei.sweep.lattice", "vei.experiments.boundary"},
        "vei.cli.main": {"vei.sweep.run", "vei.cli.run"},
        "vei.boxes": {"vei.errors", "vei.types", "vei.config"},
        "vei.types": {"vei.errors"},
    }
    bad = _direction_violations(graph)
    assert [line.split(" (")[0].strip() for line in bad] == [
        "vei.metrics.ttc -> vei.models.geometry",
        "vei.models.sfm -> vei.sim.engine",
        "vei.export.openscenario -> vei.sim",
        "vei.sweep.riskmap -> vei.experiments.boundary",
        "vei.sweep.run -> vei.cli.main",
        "vei.boxes -> vei.config",
    ]


def test_no_module_over_600_lines():
    too_long = sorted(
        (n, str(p.relative_to(SRC.parent)))
        for p in _modules().values()
        if (n := p.read_bytes().count(b"\n")) > MAX_LINES
    )
    assert not too_long, f"{len(too_long)} module(s) over {MAX_LINES} lines:\n" + "\n".join(
        f"  {n:5d} {p}" for n, p in sorted(too_long, reverse=True)
    )


def test_imports_are_resolved_like_python_does(tmp_path):
    """Hand-made module vei.sim.engine: absolute, relative, submodule and in-function imports."""
    src = tmp_path / "engine.py"
    src.write_text(
        "import numpy\n"
        "import vei.errors\n"
        "from vei.sim import kernel\n"
        "from vei.sim.state import SimState\n"
        "from . import params\n"
        "from ..metrics.ttc import ttc\n"
        "def f():\n"
        "    from vei.io.atomic import write_json\n"
        "    from vei import config\n"
    )
    known = dict.fromkeys(
        ["vei", "vei.errors", "vei.config", "vei.sim", "vei.sim.engine", "vei.sim.kernel",
         "vei.sim.state", "vei.sim.params", "vei.metrics", "vei.metrics.ttc", "vei.io",
         "vei.io.atomic"],
        src,
    )  # fmt: skip
    assert _imports("vei.sim.engine", src, known) == {
        "vei.errors", "vei.sim.kernel", "vei.sim.state", "vei.sim.params", "vei.metrics.ttc",
        "vei.io.atomic", "vei.config",
    }  # fmt: skip
    assert "vei.sim.state" in _imports("vei.sim.engine", src, known)
    typed = tmp_path / "typed.py"
    typed.write_text(
        "from typing import TYPE_CHECKING\nimport typing\nfrom vei import errors\n"
        "if TYPE_CHECKING:\n    from vei.sim.state import SimState\n"
        "if typing.TYPE_CHECKING:\n    import vei.config\n"
    )
    assert _imports("vei.sim.engine", typed, known) == {
        "vei.errors", "vei.sim.state", "vei.config"
    }  # fmt: skip
    assert _imports("vei.sim.engine", typed, known, runtime_only=True) == {"vei.errors"}
    pkg = tmp_path / "__init__.py"
    pkg.write_text("from . import engine\nfrom .kernel import step\n")
    assert _imports("vei.sim", pkg, known) == {"vei.sim.engine", "vei.sim.kernel"}
