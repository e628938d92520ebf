"""The package's shape: no import circle between its modules and no module over 600 lines.

The import graph is read from the source with :mod:`ast` (nothing is imported or run):

* every ``import`` and ``from ... import`` of a module of the package counts, wherever it
  stands -- at module level **and inside functions**. A lazy import inside a function is how
  a circle is usually hidden (``core/pipeline/sparse.py`` took ``_prepare`` from ``core/solve.py``
  that way while ``solve.py`` imported it back); it still ties the two modules, and the first
  call that runs it depends on the other module having finished loading. So a lazy import is
  an arrow like any other.
* ``importlib.import_module("rwhec_ros....")`` with a literal name counts as an import too.
* imports under ``if TYPE_CHECKING:`` do not count: they never run.
* ``from pkg import name`` is an arrow to ``pkg.name`` when that is a module of the package,
  else to ``pkg`` (its ``__init__``); relative imports are resolved against the importing
  module's package.
* the implicit import of a module's enclosing packages is not an arrow: Python puts a package
  in ``sys.modules`` before it runs any of its submodules, so a submodule never waits for its
  package's ``__init__`` to finish, and counting it would make every package whose
  ``__init__`` re-exports its submodules a circle.

A module's length is its number of lines (as ``wc -l`` counts them), docstrings and comments
included: the rule is about what a reader has to hold in mind.

Inside ``rwhec_ros/core`` the subpackages are the stages of a solve, and a stage imports only the
stages before it (:data:`CORE_STAGES`), so that the layout reads in the order the solve runs.
The old module paths of ``rwhec_ros/core`` kept for one release (:data:`DEPRECATED_PATHS`) must
give the very objects of their new homes.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

PACKAGE = "rwhec_ros"
ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 600

#: Offences being fixed in parallel branches, tolerated until those branches are merged; the lead
#: empties this set at the merge. Nothing else may be added: a new offence is fixed, not listed.
#: A module path (relative to the repository) excuses that module's length; a frozenset of
#: module names excuses exactly that circle. An entry that is no longer an offence fails the
#: test, so that it is removed.
KNOWN_EXCEPTIONS: set[str | frozenset[str]] = set()


#: The parts of ``rwhec_ros.core`` in the order a solve runs them; each may import only itself and
#: the parts before it. A new module or subpackage of core/ goes into the stage it belongs to.
CORE_STAGES = (
    "numerics",  # linear algebra proven in floating point; knows nothing of the problem
    "lie",  # SO(3)/SE(3) helpers
    "problem",  # the input: the camera-target graph and its pairs
    "result",  # results, certificates and statuses
    "model",  # the cost, the gauge fix, the reduction, the sparse form, re-centring
    "initial",  # the closed-form initial estimate
    "local",  # Riemannian Newton, dense and sparse
    "certify",  # the certificate, its multipliers and the SDP
    "pipeline",  # the dense and the large-problem path of a solve
    "solve",  # the one entry point
    "analysis",  # information, uncertainty, validation, guidance
    "refine",  # the corner-level refinement of the certified optimum
    "identifiability",
    "outliers",
    "baselines",
    "verdict",  # reads everything above
)

#: Old module paths of core/ kept as re-exports for one release, and their new homes.
DEPRECATED_PATHS = {
    "cost": ("rwhec_ros.core.model.cost", "rwhec_ros.core.model.reduction"),
    "gauge": ("rwhec_ros.core.model.gauge",),
    "certificate": ("rwhec_ros.core.certify.dense",),
    "relaxation": ("rwhec_ros.core.certify.relaxation",),
    "local_solver": ("rwhec_ros.core.local.dense", "rwhec_ros.core.certify.multipliers"),
    "uncertainty": ("rwhec_ros.core.analysis.uncertainty",),
    "validation": ("rwhec_ros.core.analysis.validation",),
    "guidance": ("rwhec_ros.core.analysis.guidance",),
    "synthetic": ("rwhec_ros.simulation.synthetic",),
    "scenarios": ("rwhec_ros.simulation.scenarios",),
    "lom": ("rwhec_ros.core.baselines.lom_solver",),
}


def _modules() -> dict[str, Path]:
    """Module name -> path for every ``.py`` file of the package (a package is its
    ``__init__``)."""
    out = {}
    for path in sorted((ROOT / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_nodes(tree: ast.AST):
    """Every import node of ``tree`` outside ``if TYPE_CHECKING:`` blocks, and every
    ``import_module("literal")`` call."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif (isinstance(node, ast.Call) and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
              and ((isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                   or (isinstance(node.func, ast.Name) and node.func.id == "import_module"))):
            yield ast.Import(names=[ast.alias(name=node.args[0].value)])
        stack.extend(ast.iter_child_nodes(node))


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of the package it imports (see the module docstring)."""
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        package = name if is_package else name.rpartition(".")[0]
        for node in _import_nodes(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                targets = [f"{target}.{alias.name}" if f"{target}.{alias.name}" in modules
                           else target for alias in node.names]
            graph[name].update(t for t in targets if t in modules and t != name)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each as one
    closed walk through all of its modules is not needed: a cycle through its first module is
    printed instead (:func:`_one_cycle`)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0

    def strongconnect(v: str) -> None:  # the graph has a few hundred modules: recursion is fine
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strongconnect(w)
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
                components.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return components


def _one_cycle(graph: dict[str, set[str]], component: list[str]) -> list[str]:
    """A shortest closed path ``a -> ... -> a`` through the component's first module."""
    members = set(component)
    start = component[0]
    parents: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(parents[path[-1]])
                    return [*reversed(path), start]
                if w not in parents:
                    parents[w] = v
                    nxt.append(w)
        frontier = nxt
    raise AssertionError(f"no cycle through {start}")  # a component of size > 1 has one


def test_the_graph_reads_known_arrows() -> None:
    """The reader of imports finds arrows of each kind (else an empty graph would pass)."""
    graph = import_graph()
    assert "rwhec_ros.core.lie" in graph["rwhec_ros.data.rosbag"]  # ``from ..core.lie import``
    assert "rwhec_ros.core.solve" in graph["rwhec_ros.session.live_solve"]  # in a function
    assert graph["rwhec_ros.core.verdict"] >= {"rwhec_ros.core.verdict.fit"}  # ``from .fit``
    cycle = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    comps = _cycles(cycle)
    assert comps == [["a", "b", "c"]]
    assert _one_cycle(cycle, comps[0]) == ["a", "b", "c", "a"]


def test_no_import_cycle() -> None:
    graph = import_graph()
    found = {frozenset(c): c for c in _cycles(graph)}
    offences = [" -> ".join(_one_cycle(graph, c)) for key, c in found.items()
                if key not in KNOWN_EXCEPTIONS]
    assert not offences, "import circles in the package:\n" + "\n".join(offences)
    stale = [sorted(e) for e in KNOWN_EXCEPTIONS if isinstance(e, frozenset) and e not in found]
    assert not stale, f"KNOWN_EXCEPTIONS lists circles that are gone, remove them: {stale}"


def test_no_module_over_600_lines() -> None:
    lengths = {path.relative_to(ROOT).as_posix(): len(path.read_text(encoding="utf-8")
                                                      .splitlines())
               for path in _modules().values()}
    offences = [f"{p}: {n} lines" for p, n in sorted(lengths.items())
                if n > MAX_LINES and p not in KNOWN_EXCEPTIONS]
    assert not offences, f"modules over {MAX_LINES} lines:\n" + "\n".join(offences)
    stale = [e for e in KNOWN_EXCEPTIONS if isinstance(e, str) and lengths.get(e, 0) <= MAX_LINES]
    assert not stale, f"KNOWN_EXCEPTIONS lists modules now within {MAX_LINES} lines: {stale}"


def _core_part(module: str) -> str | None:
    """``rwhec_ros.core.model.cost`` -> ``model``; None outside core/ and for core/ itself."""
    parts = module.split(".")
    return parts[2] if parts[:2] == ["rwhec_ros", "core"] and len(parts) > 2 else None


def test_core_stages_import_only_earlier_stages() -> None:
    graph = import_graph()
    rank = {name: i for i, name in enumerate(CORE_STAGES)}
    unplaced, upward = set(), []
    for module, targets in sorted(graph.items()):
        part = _core_part(module)
        if part is None or part in DEPRECATED_PATHS:
            continue
        if part not in rank:
            unplaced.add(part)
            continue
        for target in sorted(targets):
            other = _core_part(target)
            if other is None or other == part:
                continue
            assert other not in DEPRECATED_PATHS, f"{module} imports the deprecated {target}"
            if other in rank and rank[other] > rank[part]:
                upward.append(f"{module} ({part}) -> {target} ({other})")
    assert not unplaced, f"parts of core/ in no stage of CORE_STAGES: {sorted(unplaced)}"
    assert not upward, "imports from a stage to a later one:\n" + "\n".join(upward)


@pytest.mark.parametrize("old", sorted(DEPRECATED_PATHS))
def test_deprecated_paths_give_the_same_objects(old: str) -> None:
    shim = importlib.import_module(f"rwhec_ros.core.{old}")
    assert "deprecated" in (shim.__doc__ or "").lower()
    homes = [importlib.import_module(m) for m in DEPRECATED_PATHS[old]]
    expected = [name for home in homes for name in home.__all__]
    assert sorted(shim.__all__) == sorted(expected)
    for home in homes:
        for name in home.__all__:
            assert getattr(shim, name) is getattr(home, name), (old, name)
