"""Mutation testing of the certification logic: do the tests notice when it is wrong?

A small AST mutator (no third-party tool): each mutant changes ONE thing in one of the target
modules -- an arithmetic or comparison operator, a boolean connective, a ``not``, a numeric
constant (x100, /100, +-1, 0 <-> 1), ``min`` <-> ``max``, an ``abs`` dropped, a unary minus
dropped, ``True`` <-> ``False`` -- in a private copy of the repository, and runs the tests that
reach the mutated code. A mutant is *killed* when a test fails (or the run exceeds the
timeout), *survives* otherwise. Survivors are listed, each either killed later by a new test or
argued equivalent in ``EQUIVALENT`` (one line each).

Which tests (``--select coverage``, the default): the suite runs once under ``coverage`` with one
context per test (a small pytest plugin written into the private copy), which gives, for every
line of the targets, the tests that execute it and each test's duration. A mutant then runs
``pytest -x`` on the tests that execute its line(s), from at most ``--max-files`` test files (the
target's own ``TESTS`` files first: every file costs its imports), fastest first, within
``--budget`` seconds;
a mutant at module or class level (a default value, run at import) runs the tests of the
target's ``TESTS`` files instead; a mutant on a line no test executes survives without a run.
``--select files`` runs every test of the ``TESTS`` files (slow: minutes per surviving mutant).

Targets (``TARGETS``): ``rwhec_ros/core/certify/dense.py``, ``rwhec_ros/core/numerics/verified.py``
and the large-rig path's ``rwhec_ros/core/certify/sparse.py`` (every line but docstrings), and
the status decisions of the solve's paths, ``rwhec_ros/core/pipeline/dense.py``, ``common.py``,
``statuses.py`` and ``sparse.py`` (the functions named there).

Usage (from the repository root; prints Markdown; the coverage run of the suite takes ~5-10 min,
the mutants ~3-5 s each on 2 cores)::

    python benchmarks/mutation.py --jobs 2 --log run1.jsonl --coverage-map cov.json \
        > benchmarks/mutation.md
    python benchmarks/mutation.py --list             # the mutants only, no test runs
    # after adding tests: run only the survivors of run1 again, report on every mutant
    python benchmarks/mutation.py --jobs 2 --rerun-survivors run1.jsonl --log run2.jsonl \
        > benchmarks/mutation.md
"""

from __future__ import annotations

import argparse
import ast
import copy
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

TARGETS = {
    "rwhec_ros/core/certify/dense.py": None,  # every function and class
    "rwhec_ros/core/numerics/verified.py": None,
    "rwhec_ros/core/pipeline/dense.py": {"_certify", "solve_fast_dense", "solve_sdp", "_estimate"},
    "rwhec_ros/core/pipeline/common.py": {"failed_certificate"},
    "rwhec_ros/core/pipeline/statuses.py": {
        "check_identifiability", "_downgrade", "_rotation_gauge_words",
    },
    # the large-rig path (issue 14): its certificate and the status decisions of its solve
    "rwhec_ros/core/certify/sparse.py": None,
    "rwhec_ros/core/pipeline/sparse.py": {"solve_fast_sparse", "failed_result"},
}

#: The tests that reach each target, fastest first (``pytest -x`` stops at the first failure).
TESTS = {
    "rwhec_ros/core/certify/dense.py": ["test/core/test_certificate.py", "test/core/test_gauge.py",
                                      "test/core/test_solve.py"],
    "rwhec_ros/core/numerics/verified.py": ["test/core/test_verified_rounding.py",
                                   "test/core/test_verified.py", "test/core/test_certificate.py"],
    **{f"rwhec_ros/core/pipeline/{name}.py": ["test/core/test_solve_status.py",
                                              "test/core/test_certificate.py",
                                              "test/core/test_gauge.py", "test/core/test_solve.py"]
       for name in ("dense", "common", "statuses")},
    "rwhec_ros/core/certify/sparse.py": ["test/core/test_sparse_certificate_paths.py",
                                             "test/core/test_sparse_path.py",
                                             "test/core/test_gauge.py"],
    "rwhec_ros/core/pipeline/sparse.py": ["test/core/test_sparse_fast.py",
                                      "test/core/test_sparse_path.py",
                                      "test/core/test_gauge.py"],
}

#: Mutants argued equivalent (no observable change), keyed by (file, source line, mutation).
_CERT = "rwhec_ros/core/certify/dense.py"
_DENSE = "rwhec_ros/core/pipeline/dense.py"
_STATUSES = "rwhec_ros/core/pipeline/statuses.py"
_TERMS = "terms = int(np.diff(constraints.C.tocsr().indptr).max(initial=1))"
EQUIVALENT: dict[tuple[str, str, str], str] = {
    (_CERT, "block_lower: float = 1.0", "1.0 -> x100"):
        "ExactReduction's schur term is ny r^2 / (block_lower scale) with r = residual_norm = 0 "
        "for every exact reduction: 0 whatever block_lower",
    (_CERT, "block_lower: float = 1.0", "1.0 -> /100"):
        "as above: the residual norm of an exact reduction is 0",
    (_CERT, _TERMS, "1 -> 2"):
        "initial= only matters for an empty constraint set; the s-s entry carries every "
        "rotation's constant term, so the maximum is >= 2 (asserted in test_certificate)",
    (_CERT, _TERMS, "1 -> 0"):
        "as above: the maximum over a non-empty constraint set is >= 2",
    (_CERT, "err_rows = (gamma(terms + 1) * K_abs.sum(axis=1)", "1 -> 0"):
        "K_abs = |C| |lambda| is symmetric (every constraint matrix is): its column sums are its "
        "row sums (up to the summation order's rounding, far below gamma)",
    (_CERT, "+ gamma(3) * (np.abs(Qs).sum(axis=1) + np.abs(K).sum(axis=1)))", "1 -> 0"):
        "|Q'| and |K| are symmetric: column sums = row sums (as above)",
    (_CERT, "rows = (reduced.err_rows / scale) * (1.0 + gamma(2)) + UNIT_ROUNDOFF * np.abs(Z)"
            ".sum(axis=1)", "2 -> 1"):
        "1.0 + gamma(1) and 1.0 + gamma(2) are the same double, 1 + 2^-52 (gamma(1) is just above "
        "half an ulp of 1 and rounds up): asserted in test_certificate",
    (_CERT, "rows = (reduced.err_rows / scale) * (1.0 + gamma(2)) + UNIT_ROUNDOFF * np.abs(Z)"
            ".sum(axis=1)", "1 -> 0"):
        "sum(axis=0) of |Z|: Z is symmetric (formed as 0.5 (Z + Z^T) and documented so), its "
        "column sums are its row sums (up to the summation order's rounding, far below gamma)",
    (_CERT, "rows = (rows + z_err_rows) * (1.0 + gamma(3))", "3 -> 4"):
        "1.0 + gamma(3) and 1.0 + gamma(4) are the same double, 1 + 2^-51: asserted in "
        "test_certificate",
    **{(_DENSE, "if abs(v[-1]) > 1e-8 * np.linalg.norm(v):", d):
       "the division of the null vector by s is redundant: rotations_from_vector divides every "
       "block by the mean cube-root determinant, which removes any common scale and sign (only "
       "the rounding differs)" for d in ("Gt -> GtE", "drop abs", "drop USub", "1 -> 2",
                                          "1 -> 0", "Mult -> Div", "1e-08 -> x100",
                                          "1e-08 -> /100")},
    **{("rwhec_ros/core/numerics/verified.py", src, d): why for src, d, why in [
        ("if n == 0 or not np.any(A):", "Or -> And",
         "for a zero A the power iteration stops at once (top = 0) and returns 0 as well"),
        ("if n == 0 or not np.any(A):", "0 -> -1",
         "n = 0 still returns 0: np.any of an empty array is False"),
        ("if not np.isfinite(top) or top <= 0.0:", "LtE -> Lt",
         "top = 0 exactly only for a zero A, returned before the loop"),
        ("x = np.maximum(y / top, 1e-30)", "1e-30 -> x100",
         "the floor only keeps x positive where (Bx)_i = 0; those ratios are 0 whatever it is"),
        ("x = np.maximum(y / top, 1e-30)", "1e-30 -> /100", "as above"),
        ("n = A.shape[0]", "0 -> -1", "A is square (checked by the caller): shape[-1] = shape[0]"),
        ("R = scipy.linalg.cholesky(B, lower=False, check_finite=False)", "False -> True",
         "lower: rho(|L|^T |L|) = rho(|L| |L|^T), the same radius; check_finite: B is finite "
         "(checked before)"),
        ("shift_rounding = UNIT_ROUNDOFF * float(np.max(np.abs(np.diag(B)))) if n else 0.0",
         "0.0 -> 1.0", "n = 0 never reaches the factorisation (returned before)"),
        ("if A.ndim != 2 or A.shape != (n, n):", "Or -> And",
         "a tuple comparison of the shape already differs for any ndim != 2"),
        ("estimate = float(smallest_eigenvalues(A, 1)[0])", "1 -> 2",
         "the first of the two smallest eigenvalues is the smallest"),
        ("estimate = float(smallest_eigenvalues(A, 1)[0])", "0 -> -1",
         "the last of one eigenvalue is the first"),
        ("return 1.0 + 0.5 * np.sin(np.arange(m) * 1.7)", "Add -> Sub",
         "any fixed positive start vector with mixed components serves (asserted in "
         "test_verified_rounding); the eigenvalues do not depend on it"),
        ("return 1.0 + 0.5 * np.sin(np.arange(m) * 1.7)", "Mult -> Div", "as above"),
        ("return 1.0 + 0.5 * np.sin(np.arange(m) * 1.7)", "1.7 -> x100", "as above"),
        ("d = Z.shape[0]", "0 -> 1", "Z is square: shape[1] = shape[0]"),
        ("d = Z.shape[0]", "0 -> -1", "Z is square: shape[-1] = shape[0]"),
        ("if k <= 0:", "LtE -> Lt", "k = 0 falls through to eigvalsh(Z)[:0], also empty"),
        ("if k <= 0:", "0 -> -1", "as above"),
        ("factor = scipy.linalg.cho_factor(Z + shift * np.eye(d), lower=True,", "True -> False",
         "cho_solve reads the triangle cho_factor says it wrote: the same solves"),
        ("check_finite=False)", "False -> True", "Z is finite here (checked by the callers)"),
        ("(d, d), matvec=lambda b: scipy.linalg.cho_solve(factor, b, check_finite=False),",
         "False -> True", "the right-hand sides of ARPACK are finite"),
    ]},
    # -- the status decisions of the solve (issue 19, second pass; then in solve.py) --
    **{(_DENSE, "v = v / v[-1]", d):
       "a common factor of the null vector (s, or the entry v[1], v[-2], v[0]), removed by "
       "rotations_from_vector's mean cube-root determinant with its sign; only an entry that is "
       "exactly 0.0 would differ" for d in ("Div -> Mult", "drop USub", "1 -> 2", "1 -> 0")},
    **{(_DENSE if src.startswith(("if form", "if abs(v")) else _STATUSES, src, d): why
       for src, d, why in [
        ('if form == "arrow" and split is None:', "And -> Or",
         "arrow_split returns None only below 2 frames and every Problem has an X and a Y frame: "
         "the split then computed for the full or reduced form is never used"),
        ("if abs(v[-1]) > 1e-8 * np.linalg.norm(v):", "Gt -> Lt",
         "dividing only when |s| <= 1e-8 |v| is again a common factor (removed by "
         "rotations_from_vector, as for this line's other mutants) unless s is exactly 0.0"),
        ("t = np.concatenate([res.X, res.Y])[:, :3, 3].reshape(-1)", "1 -> 2",
         "numpy reads any negative size as the inferred one: reshape(-2) is reshape(-1)"),
        ("v = V[:, i].reshape(-1, 3)", "1 -> 2",
         "numpy reads any negative size as the inferred one: reshape(-2, 3) is reshape(-1, 3)"),
        ("problem.frame_names, np.concatenate([res.X, res.Y]), strict=True)}", "True -> False",
         "frame_names has M + P names and X, Y hold M + P transforms by construction: zip never "
         "sees unequal lengths"),
        ("if abs(got - p.value_m) > 1e-4:", "Gt -> GtE",
         "differs only when a prior is missed by exactly 1e-4 m"),
        ("weak = np.where(np.abs(w) <= 10.0 * null_tol)[0]", "0 -> -1",
         "np.where of one condition returns a 1-tuple: [-1] is [0]"),
        ("if par and par[0][int(np.argmax(np.abs(par[0])))] < 0:", "Lt -> LtE",
         "the largest-magnitude component of an axis of norm >= 0.1 is never 0"),
        ("if par and par[0][int(np.argmax(np.abs(par[0])))] < 0:", "0 -> -1",
         "(of this line's two '0 -> -1' mutants the one surviving: par[-1][i], i the first axis' "
         "largest component; test_solve_status kills the other) the sign shows only when every "
         "axis reads the same, and then par[-1][i] has the sign of par[0][i] (|.| >= 1/sqrt 3)"),
    ]},
    (_CERT, "reduced = ExactReduction(Z.shape[0])", "0 -> 1"):
        "Z is square (the eigensolver refuses anything else): shape[1] = shape[0]",
    (_CERT, "reduced = ExactReduction(Z.shape[0])", "0 -> -1"):
        "Z is square: shape[-1] = shape[0]",
    (_CERT, "z_err_rows = np.zeros(Z.shape[0])", "0 -> 1"):
        "Z is square: shape[1] = shape[0]",
    (_CERT, "z_err_rows = np.zeros(Z.shape[0])", "0 -> -1"):
        "Z is square: shape[-1] = shape[0]",
}

# the large-rig certificate (issue 19): rwhec_ros/core/certify/sparse.py
_SC = "rwhec_ros/core/certify/sparse.py"
_SC_EY = "e_y = float(min(c_y.sum(), ny * c_y.max(initial=0.0)) * (1.0 + gamma(ny)))"
_SC_MU0 = "mu0 = gamma(64) * float(np.abs(data[pattern.diag[nf:]]).mean()) + 1e-300"
_SC_SLOPE = "if not np.isfinite(slope) or abs(slope) < 1e-300:"
_SC_TMAX = ("t_max = float(np.abs(data0).max()) / max(float(np.abs(hand[0]).max()), "
            "1e-300)")
_SC_BELOW = "below = -1 if probe is None else probe.n_negative"
_SC_TARGET = ("target = np.array([slot.get((int(a), int(b)), -1) for a, b in zip(P, Qi, "
              "strict=True)])")
EQUIVALENT.update({
    (_SC, "self.abs_rows_Q = np.asarray(abs(Qs).sum(axis=1)).ravel()", "1 -> 0"):
        "Q_s is stored exactly symmetric (sparse_problem: U + triu(U, 1)^T): column sums = row "
        "sums up to the summation order's rounding, far below gamma_2",
    (_SC, "def matrix_data(self, Gamma: np.ndarray, lambda_s: float, t: float = 0.0,",
     "0.0 -> 1.0"):
        "t is read only under `t != 0.0 and hand is not None`; every call that omits t also "
        "omits hand",
    (_SC, "k_rows[nf: nf + 9 * n] = np.repeat(np.abs(Gamma).sum(axis=2), 3, axis=1).ravel()",
     "2 -> 1"):
        "Gamma = 0.5 (A + A^T) is exactly symmetric in floating point (asserted in "
        "test_sparse_certificate_paths): row sums = column sums",
    (_SC, "c *= 1.0 + gamma(4)", "4 -> 3"):
        "1 + gamma_3 and 1 + gamma_4 are the same double (asserted in "
        "test_sparse_certificate_paths)",
    (_SC, "eig_term = float(ny * mu * (1.0 + gamma(2)))", "2 -> 1"):
        "1 + gamma_1 and 1 + gamma_2 are the same double (asserted in "
        "test_sparse_certificate_paths)",
    (_SC, "short = c[:nf] > delta", "Gt -> GtE"):
        "differs only when a rounding bound equals its shift exactly (then one more refit; the "
        "theorem needs delta >= c, true either way)",
    (_SC, _SC_EY, "0.0 -> 1.0"):
        "ny = len(c_y), so sum(c_y) <= ny max(c_y) <= ny max(c_y, 1): the min is the sum either "
        "way (initial= only matters for an empty c_y, and y is never empty)",
    **{(_SC, _SC_MU0, d): "gamma_64 mean|Z_yy| >= 1e-284 for any cost with a rotation term "
       "(the y diagonal holds the rotations' squared-residual weights): adding 1e-298, 1e-300, "
       "1e-302 or subtracting 1e-300 gives the same double"
       for d in ("Add -> Sub", "1e-300 -> x100", "1e-300 -> /100")},
    (_SC, "null_dim, trivial_s = -1, False", "False -> True"):
        "without a bound the status is ill_conditioned; trivial_s only adds a phrase to a "
        "certified message",
    (_SC, "c = V[:, :2].T @ (y / np.linalg.norm(y))", "2 -> 3"):
        "only c[0] and c[1] are read: a third entry changes nothing",
    (_SC, "c = V[:, :2].T @ (y / np.linalg.norm(y))", "Div -> Mult"):
        "v is normalised and the test nv > 0 is scale-free: scaling y by |y|^2 instead of "
        "1/|y| gives the same direction (up to rounding)",
    **{(_SC, _SC_SLOPE, d): "the guard is redundant: a NaN slope gives a NaN t and |slope| < "
       "1e-298 a first t = 2 null_tol/|slope| > 1e292 > t_max = max|Z| / max|D| (max|D| >= "
       "1/2, the column-norm weights): the loop does not run and None is returned either way "
       "(the slope is finite: v2 is a unit vector, D's entries are bounded by |R_ij| <= 1)"
       for d in ("Or -> And", "Lt -> LtE", "1e-300 -> x100", "1e-300 -> /100")},
    **{(_SC, _SC_TMAX, d): "max|D| >= 1/2 (the -1/2 weights of the column-norm constraints): "
       "the 1e-300 floor of max(., 1e-300) never applies" for d in ("1e-300 -> x100",
                                                                   "1e-300 -> /100")},
    (_SC, "while abs(t) <= t_max:", "LtE -> Lt"):
        "differs only when |t| = t0 4^k equals the ratio of two maxima t_max exactly",
    **{(_SC, _SC_BELOW, d): "any value other than 1 fails the screen `below == 1`: -2 and 0 "
       "act as -1" for d in ("1 -> 2", "1 -> 0")},
    (_SC, "slot = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(pp, qq, strict=True))}",
     "True -> False"):
        "pp and qq come from one np.triu_indices call: the same length, so strict= never raises",
    (_SC, _SC_TARGET, "True -> False"):
        "P and Qi are the parallel index arrays of one constraint pattern: the same length",
    (_SC, _SC_TARGET, "1 -> 2"):
        "the marker of a lower-half entry only has to be negative: keep = target >= 0 drops -2 "
        "as it drops -1",
    (_SC, "and cert.lambda_min >= -opts.null_tol):", "GtE -> Gt"):
        "differs only when the estimated lambda_min equals -null_tol exactly (as for the same "
        "test in solve.py)",
})


@dataclass
class Mutant:
    file: str
    lineno: int
    source: str
    description: str
    text: str  # the mutated module
    lines: tuple[int, ...] = ()  # every source line the mutated node spans
    in_function: bool = True  # False: module or class level (runs at import time)


class _Sites(ast.NodeVisitor):
    """Collect mutation sites (node path + kind) inside the target functions."""

    def __init__(self, functions: set[str] | None, docstrings: set[int]):
        self.functions = functions
        self.docstrings = docstrings
        self.stack: list[str] = []
        self.kinds: list[str] = []  # "def" or "class", parallel to ``stack``
        self.sites: list[tuple[ast.AST, str, bool]] = []  # (node, kind, inside a function)

    def _in_function(self, node: ast.AST) -> bool:
        """Inside a function body (runs when called), not a default or decorator argument."""
        return "def" in self.kinds and not getattr(node, "_in_signature", False)

    def _active(self) -> bool:
        return self.functions is None or any(f in self.functions for f in self.stack)

    def visit_FunctionDef(self, node):
        # defaults and decorators are evaluated once, when the module is imported
        at_def = node.args.defaults + [d for d in node.args.kw_defaults if d is not None] + \
            node.decorator_list
        for sub in at_def:
            for n in ast.walk(sub):
                n._in_signature = True
        self.stack.append(node.name)
        self.kinds.append("def")
        self.generic_visit(node)
        self.stack.pop()
        self.kinds.pop()

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_ClassDef(self, node):
        self.stack.append(node.name)
        self.kinds.append("class")
        self.generic_visit(node)
        self.stack.pop()
        self.kinds.pop()

    def generic_visit(self, node):
        if self._active() and id(node) not in self.docstrings:
            if isinstance(node, (ast.BinOp, ast.Compare, ast.BoolOp, ast.UnaryOp)):
                self.sites.append((node, type(node).__name__, self._in_function(node)))
            elif isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and \
                    not isinstance(node.value, str):
                self.sites.append((node, "Constant", self._in_function(node)))
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                    node.func.id in ("min", "max", "abs"):
                self.sites.append((node, "Call", self._in_function(node)))
        super().generic_visit(node)


_BIN_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
             ast.Pow: ast.Mult, ast.FloorDiv: ast.Mult}
_CMP_SWAP = {ast.Lt: [ast.LtE, ast.Gt], ast.LtE: [ast.Lt, ast.Gt], ast.Gt: [ast.GtE, ast.Lt],
             ast.GtE: [ast.Gt, ast.Lt], ast.Eq: [ast.NotEq], ast.NotEq: [ast.Eq],
             ast.Is: [ast.IsNot], ast.IsNot: [ast.Is], ast.In: [ast.NotIn],
             ast.NotIn: [ast.In]}


def _variants(node: ast.AST, kind: str) -> list[tuple[str, callable]]:
    """(description, function mutating a deep copy of ``node`` in place) pairs."""
    out = []
    if kind == "BinOp" and type(node.op) in _BIN_SWAP:
        new = _BIN_SWAP[type(node.op)]
        out.append((f"{type(node.op).__name__} -> {new.__name__}",
                    lambda n, new=new: setattr(n, "op", new())))
    elif kind == "Compare":
        for i, op in enumerate(node.ops):
            for new in _CMP_SWAP.get(type(op), []):
                def f(n, i=i, new=new):
                    n.ops[i] = new()
                out.append((f"{type(op).__name__} -> {new.__name__}", f))
    elif kind == "BoolOp":
        new = ast.Or if isinstance(node.op, ast.And) else ast.And
        out.append((f"{type(node.op).__name__} -> {new.__name__}",
                    lambda n, new=new: setattr(n, "op", new())))
    elif kind == "UnaryOp" and isinstance(node.op, (ast.Not, ast.USub)):
        out.append((f"drop {type(node.op).__name__}", "REPLACE_WITH_OPERAND"))
    elif kind == "Constant":
        v = node.value
        if isinstance(v, bool):
            out.append((f"{v} -> {not v}", lambda n: setattr(n, "value", not n.value)))
        elif isinstance(v, int):
            out.append((f"{v} -> {v + 1}", lambda n: setattr(n, "value", n.value + 1)))
            out.append((f"{v} -> {v - 1}", lambda n: setattr(n, "value", n.value - 1)))
        elif isinstance(v, float):
            if v == 0.0:
                out.append(("0.0 -> 1.0", lambda n: setattr(n, "value", 1.0)))
            else:
                out.append((f"{v!r} -> x100", lambda n: setattr(n, "value", n.value * 100)))
                out.append((f"{v!r} -> /100", lambda n: setattr(n, "value", n.value / 100)))
    elif kind == "Call":
        name = node.func.id
        if name in ("min", "max"):
            new = "max" if name == "min" else "min"
            out.append((f"{name} -> {new}", lambda n, new=new: setattr(n.func, "id", new)))
        elif name == "abs" and len(node.args) == 1:
            out.append(("drop abs", "REPLACE_WITH_ARG"))
    return out


class _Replace(ast.NodeTransformer):
    def __init__(self, target_index: int, nodes: list[ast.AST], how):
        self.target = nodes[target_index]
        self.how = how

    def visit(self, node):
        if node is self.target:
            if self.how == "REPLACE_WITH_OPERAND":
                return node.operand
            if self.how == "REPLACE_WITH_ARG":
                return node.args[0]
            self.how(node)
            return node
        return super().visit(node)


def _docstring_ids(tree: ast.AST) -> set[int]:
    ids = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) and \
                isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
            ids.add(id(body[0].value))
    return ids


def generate(file: str, functions: set[str] | None) -> list[Mutant]:
    src = (ROOT / file).read_text()
    lines = src.splitlines()
    tree = ast.parse(src)
    visitor = _Sites(functions, _docstring_ids(tree))
    visitor.visit(tree)
    mutants = []
    # the copy's nodes, walked in the same order, correspond to the original's by position
    position = {id(n): i for i, n in enumerate(ast.walk(tree))}
    unmutated = ast.unparse(tree)
    for node, kind, in_function in visitor.sites:
        for desc, how in _variants(node, kind):
            tree2 = copy.deepcopy(tree)
            target = next(n for i, n in enumerate(ast.walk(tree2)) if i == position[id(node)])
            tree2 = _Replace(0, [target], how).visit(tree2)
            ast.fix_missing_locations(tree2)
            text = ast.unparse(tree2)
            if text == unmutated:
                continue
            line = lines[node.lineno - 1].strip()
            span = tuple(range(node.lineno, (node.end_lineno or node.lineno) + 1))
            mutants.append(Mutant(file, node.lineno, line, desc, text, span, in_function))
    return mutants


def _prepare_copy(dst: Path) -> None:
    """The repository's tracked files (tests read benchmarks/, config/, launch/, README.md)."""
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True)
    for rel in filter(None, listed.stdout.decode().split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)
    shared = ROOT.parent / "shared"
    if shared.exists() and not (dst.parent / "shared").exists():
        try:
            (dst.parent / "shared").symlink_to(shared)
        except OSError:
            pass


_PLUGIN = r'''
"""pytest plugin written by benchmarks/mutation.py: which test executes which target line."""
import json
import os
import time

import coverage
import pytest

_cov = coverage.Coverage(data_file=os.environ["RWHEC_MUTCOV_DATA"],
                         include=json.loads(os.environ["RWHEC_MUTCOV_INCLUDE"]))
_cov.start()
_cov.switch_context("import")
_durations = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _cov.switch_context(item.nodeid)
    t0 = time.perf_counter()
    yield
    _durations[item.nodeid] = time.perf_counter() - t0
    _cov.switch_context("between tests")


def pytest_sessionfinish(session, exitstatus):
    _cov.stop()
    _cov.save()
    with open(os.environ["RWHEC_MUTCOV_DATA"] + ".durations.json", "w") as fh:
        json.dump({"durations": _durations, "exitstatus": int(exitstatus)}, fh)
'''

_SERVER = r'''
"""Fork server written by benchmarks/mutation.py: imports the heavy third-party modules once, then
runs each request's pytest in a forked child (which imports rwhec_ros afresh from the mutated
copy, so each mutant costs the package's import, not numpy's, scipy's, cvxpy's and OpenCV's)."""
import json
import os
import signal
import sys

import matplotlib

matplotlib.use("Agg")
import cv2  # noqa: E402,F401
import cvxpy  # noqa: E402,F401
import matplotlib.pyplot  # noqa: E402,F401
import numpy  # noqa: E402,F401
import pytest  # noqa: E402
import scipy.linalg  # noqa: E402,F401
import scipy.optimize  # noqa: E402,F401
import scipy.sparse.linalg  # noqa: E402,F401
import scipy.spatial.transform  # noqa: E402,F401
import yaml  # noqa: E402,F401

assert not any(m.startswith("rwhec_ros") for m in sys.modules)
print("ready", flush=True)
for line in sys.stdin:
    req = json.loads(line)
    pid = os.fork()
    if pid == 0:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        signal.alarm(max(1, int(req["timeout"])))
        try:
            code = int(pytest.main(req["args"]))
        except BaseException:
            code = 98
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        out = "timeout" if sig == signal.SIGALRM else f"signal {sig}"
    else:
        out = os.WEXITSTATUS(status)
    print(json.dumps({"code": out}), flush=True)
'''


class _Server:
    """One fork server per private copy (see ``_SERVER``)."""

    def __init__(self, workdir: Path):
        (workdir / "_rwhec_mutserver.py").write_text(_SERVER)
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", OMP_NUM_THREADS="1",
                   OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
        self.proc = subprocess.Popen([sys.executable, "_rwhec_mutserver.py"], cwd=workdir,
                                     env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True)
        if self.proc.stdout.readline().strip() != "ready":
            sys.exit("the mutation fork server did not start")

    def run(self, args: list[str], timeout: float):
        self.proc.stdin.write(json.dumps({"args": args, "timeout": timeout}) + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())["code"]

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


_NOT_A_TEST = {"", "import", "between tests"}


@dataclass
class CoverageMap:
    """Which tests execute which line of each target, and how long each test took."""

    lines: dict[str, dict[int, set[str]]]  # target file -> line -> pytest node ids
    durations: dict[str, float]  # node id -> seconds (measured under coverage: an upper bound)
    seconds: float  # wall time of the coverage run

    def select(self, m: Mutant, budget: float, max_files: int) -> list[str]:
        """The tests to run against ``m``: those that execute its line(s), from at most
        ``max_files`` test files (the target's own ``TESTS`` files first, then the files with the
        fastest such test: each file costs its imports at start-up), fastest first, until their
        summed duration reaches ``budget`` seconds (at least one). A line at module or class level
        (a default, a constant) runs at import: the tests of ``TESTS[m.file]`` instead. Empty: no
        test executes the mutated code."""
        if m.in_function:
            ids: set[str] = set()
            for line in m.lines:
                ids |= self.lines.get(m.file, {}).get(line, set())
            ids -= _NOT_A_TEST
        else:
            ids = {n for n in self.durations if n.split("::")[0] in TESTS[m.file]}
        dur = lambda n: self.durations.get(n, 0.0)
        fastest: dict[str, float] = {}
        for n in ids:
            f = n.split("::")[0]
            fastest[f] = min(fastest.get(f, float("inf")), dur(n))
        own = TESTS[m.file]
        files = sorted(fastest, key=lambda f: (f not in own, own.index(f) if f in own else 0,
                                               fastest[f], f))[:max_files]
        picked, total = [], 0.0
        for nid in sorted((n for n in ids if n.split("::")[0] in files), key=lambda n: (dur(n), n)):
            if picked and total + dur(nid) > budget:
                break
            picked.append(nid)
            total += dur(nid)
        return picked

    def save(self, path: Path) -> None:
        path.write_text(json.dumps({"lines": {f: {str(k): sorted(v) for k, v in by.items()}
                                              for f, by in self.lines.items()},
                                    "durations": self.durations, "seconds": self.seconds}))

    @classmethod
    def load(cls, path: Path) -> CoverageMap:
        d = json.loads(path.read_text())
        return cls({f: {int(k): set(v) for k, v in by.items()} for f, by in d["lines"].items()},
                   d["durations"], d["seconds"])


def coverage_map(workdir: Path, files: list[str], tests: list[str]) -> CoverageMap:
    """Run ``tests`` once under coverage with one context per test (the plugin above)."""
    import coverage

    data_file = workdir.parent / "mutcov.data"
    (workdir / "_rwhec_mutcov.py").write_text(_PLUGIN)
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", RWHEC_MUTCOV_DATA=str(data_file),
               RWHEC_MUTCOV_INCLUDE=json.dumps([str(workdir / f) for f in files]))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-p", "_rwhec_mutcov", *tests], cwd=workdir, env=env,
                          capture_output=True)
    seconds = time.perf_counter() - t0
    info = json.loads(Path(str(data_file) + ".durations.json").read_text())
    if proc.returncode != 0:
        sys.exit("the unmutated tests fail under coverage:\n" + proc.stdout.decode()[-3000:])
    data = coverage.CoverageData(basename=str(data_file))
    data.read()
    lines: dict[str, dict[int, set[str]]] = {}
    for f in files:
        by_line = data.contexts_by_lineno(str(workdir / f))
        lines[f] = {int(k): set(v) for k, v in by_line.items()}
    return CoverageMap(lines, info["durations"], seconds)


def run_mutant(m: Mutant, workdir: Path, timeout: float, tests: list[str] | None = None,
               server: _Server | None = None) -> tuple[str, float]:
    """Run ``tests`` (default: the files of ``TESTS[m.file]``) with ``pytest -x`` on the mutant,
    in a forked child of ``server`` if given, else in a new interpreter."""
    target = workdir / m.file
    original = (ROOT / m.file).read_text()
    target.write_text(m.text)
    args = ["-x", "-q", "-p", "no:cacheprovider", *(tests if tests else TESTS[m.file])]
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    try:
        if server is not None:
            code = server.run(args, timeout)
        else:
            try:
                code = subprocess.run([sys.executable, "-m", "pytest", *args], cwd=workdir,
                                      env=env, capture_output=True, timeout=timeout).returncode
            except subprocess.TimeoutExpired:
                code = "timeout"
    finally:
        target.write_text(original)
    if code == "timeout":
        outcome = "killed (timeout)"
    elif isinstance(code, str) and code.startswith("signal"):
        # the mutant crashed the interpreter (e.g. out-of-range indices handed to compiled code):
        # the tests did not pass
        outcome = f"killed (crashed: {code})"
    elif code == 0:
        outcome = "survived"
    elif code in (3, 4, 5, 98) or isinstance(code, str):
        # internal error, usage error, no tests collected, a crash of pytest: not a kill
        outcome = f"error (pytest exit {code})"
    else:
        outcome = "killed"
    return outcome, time.perf_counter() - t0


def baseline(workdir: Path, files: list[str]) -> dict[str, float]:
    """Seconds of the unmutated test run of each target's ``TESTS`` files (they must pass)."""
    times = {}
    for f in files:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               *TESTS[f]], cwd=workdir, capture_output=True)
        if proc.returncode != 0:
            sys.exit("the unmutated tests fail:\n" + proc.stdout.decode()[-3000:])
        times[f] = time.perf_counter() - t0
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1, help="parallel test runs (default 1)")
    ap.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    ap.add_argument("--file", action="append", help="only these target files")
    ap.add_argument("--limit", type=int, default=0, help="at most this many mutants (0: all)")
    ap.add_argument("--log", type=Path, help="JSON-lines record of every mutant's outcome")
    ap.add_argument("--rerun-survivors", type=Path, metavar="LOG",
                    help="take the outcomes of an earlier run's --log and run only its survivors "
                         "again (after new tests); the report covers every mutant")
    ap.add_argument("--keep-argued", action="store_true",
                    help="with --rerun-survivors LOG: a survivor argued equivalent in EQUIVALENT "
                         "keeps its earlier outcome instead of running again")
    ap.add_argument("--report-only", action="store_true",
                    help="with --rerun-survivors LOG: print the report of LOG's outcomes (the "
                         "latest record of each mutant; logs of several runs concatenated), run "
                         "nothing")
    ap.add_argument("--select", choices=("coverage", "files"), default="coverage",
                    help="coverage (default): per mutant, the tests that execute its line, "
                         "fastest first within --budget; files: every test of the TESTS files")
    ap.add_argument("--budget", type=float, default=30.0,
                    help="coverage selection: summed duration of the tests run per mutant, in "
                         "seconds as measured under coverage (default 30)")
    ap.add_argument("--no-fork", dest="fork", action="store_false",
                    help="start a new interpreter per mutant instead of forking a server that "
                         "has imported numpy, scipy, cvxpy and OpenCV once")
    ap.add_argument("--max-files", type=int, default=3,
                    help="coverage selection: tests from at most this many test files per mutant "
                         "(default 3)")
    ap.add_argument("--coverage-map", type=Path,
                    help="coverage selection: reuse this map of an earlier coverage run if the "
                         "file exists, else save the new one there (valid while the targets and "
                         "tests are unchanged)")
    ap.add_argument("--coverage-tests", nargs="+", default=["test"],
                    help="coverage selection: the tests run once under coverage (default: the "
                         "whole suite)")
    args = ap.parse_args(argv)
    if args.report_only and args.rerun_survivors is None:
        ap.error("--report-only needs --rerun-survivors LOG (the outcomes to report)")
    files = args.file or list(TARGETS)
    mutants = [m for f in files for m in generate(f, TARGETS[f])]
    if args.limit:
        mutants = mutants[: args.limit]
    # A mutant's record in earlier logs: the latest one with the same file, source text,
    # mutation and ``nth`` (its index among the file's mutants with that text and mutation, in
    # line order: one line can hold the same mutation twice, and one text can stand on several
    # lines; unlike the line number, nth does not move when lines are added above). Records
    # written before nth was logged fall back to the same line number, then to the same text.
    # Logs of successive runs may be concatenated; only killed mutants are skipped.
    nth: list[int] = []
    seen: dict[tuple[str, str, str], int] = {}
    for m in mutants:
        k = (m.file, m.source, m.description)
        nth.append(seen.get(k, 0))
        seen[k] = nth[-1] + 1
    earlier_by: tuple[dict, dict, dict] = ({}, {}, {})
    if args.rerun_survivors:
        for line in args.rerun_survivors.read_text().splitlines():
            r = json.loads(line)
            got = (r["outcome"], r["seconds"])
            text_key = (r["file"], r["source"], r["description"])
            earlier_by[2][text_key] = got
            earlier_by[1][(r["lineno"], *text_key)] = got
            if "nth" in r:
                earlier_by[0][(r["nth"], *text_key)] = got

    def earlier(i: int) -> tuple[str, float] | None:
        m = mutants[i]
        text_key = (m.file, m.source, m.description)
        for table, key in zip(earlier_by, ((nth[i], *text_key), (m.lineno, *text_key), text_key),
                              strict=True):
            if key in table:
                return table[key]
        return None

    if args.report_only:
        # the report of earlier runs' logs (latest record per mutant), nothing is run
        results = []
        for i, m in enumerate(mutants):
            got = earlier(i)
            outcome, dt = got if got is not None else ("not run", 0.0)
            results.append((m, outcome, dt, -1))
        cover = CoverageMap.load(args.coverage_map) if args.coverage_map else None
        report(results, {}, float("nan"), cover, args)
        return 0
    if args.list:
        for m in mutants:
            print(f"{m.file}:{m.lineno}: {m.description}    | {m.source}")
        print(f"{len(mutants)} mutants", file=sys.stderr)
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="rwhec_mut_"))
    workdirs = []
    for j in range(max(1, args.jobs)):
        w = tmp / f"w{j}" / "repo"
        w.parent.mkdir(parents=True)
        _prepare_copy(w)
        workdirs.append(w)
    cover = None
    if args.select == "coverage":
        if args.coverage_map is not None and args.coverage_map.exists():
            cover = CoverageMap.load(args.coverage_map)
        else:
            cover = coverage_map(workdirs[0], files, args.coverage_tests)
            if args.coverage_map is not None:
                cover.save(args.coverage_map)
        print(f"coverage run: {cover.seconds:.0f} s, {len(cover.durations)} tests",
              file=sys.stderr)
        t_base = {}
        timeout = max(120.0, 4 * args.budget)
    else:
        t_base = baseline(workdirs[0], files)
        timeout = max(120.0, 5 * max(t_base.values()))
    servers = [_Server(w) for w in workdirs] if args.fork else [None] * len(workdirs)
    results: list[tuple] = [None] * len(mutants)
    free = list(range(len(workdirs)))
    log_lock = threading.Lock()

    def task(i: int):
        m = mutants[i]
        before, before_s = earlier(i) or (None, 0.0)
        tests = None
        if before is not None and before.startswith("killed"):
            outcome, dt = "killed (earlier run)", before_s  # the earlier run's test time
        elif (before is not None and args.keep_argued
              and (m.file, m.source, m.description) in EQUIVALENT):
            outcome, dt = before.removesuffix(" (re-run)"), before_s  # argued: not run again
        elif cover is not None and not (tests := cover.select(m, args.budget, args.max_files)):
            outcome, dt = "survived (no test executes it)", 0.0
        else:
            w = free.pop()
            try:
                outcome, dt = run_mutant(m, workdirs[w], timeout, tests, servers[w])
            finally:
                free.append(w)
        if before is not None and not outcome.startswith("killed (earlier"):
            outcome = outcome + " (re-run)"
        n_tests = len(tests) if tests is not None else -1
        results[i] = (m, outcome, dt, n_tests)
        if args.log:
            with log_lock, args.log.open("a") as fh:
                fh.write(json.dumps({"file": m.file, "lineno": m.lineno, "source": m.source,
                                     "description": m.description,
                                     "nth": nth[i], "outcome": outcome,
                                     "seconds": round(dt, 1), "tests": n_tests}) + "\n")
        done = sum(r is not None for r in results)
        print(f"[{done}/{len(mutants)}] {m.file}:{m.lineno} {m.description}: {outcome} "
              f"({dt:.0f} s, {n_tests} tests)", file=sys.stderr)

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=len(workdirs)) as ex:
        list(ex.map(task, range(len(mutants))))
    total = time.perf_counter() - t0
    for srv in servers:
        if srv is not None:
            srv.close()
    shutil.rmtree(tmp, ignore_errors=True)
    report(results, t_base, total, cover, args)
    return 0


def report(results, t_base: dict[str, float], total: float, cover: CoverageMap | None,
           args) -> None:
    print("# Mutation testing of the certification logic\n")
    cmd = " ".join(sys.argv[1:])
    print("Generated by `python benchmarks/mutation.py " + cmd + "` (see its docstring for the "
          f"mutation operators) on {time.strftime('%Y-%m-%d')}, {os.cpu_count()} CPUs"
          + (f". Whole run: {total / 60:.0f} min.\n" if total == total else
             ", from the logs of the runs named below.\n"))
    if cover is not None:
        print(f"Tests per mutant: the suite ran once under coverage ({cover.seconds:.0f} s, "
              f"{len(cover.durations)} tests, one coverage context per test); each mutant then "
              "runs `pytest -x` on the tests that execute its line(s) from at most "
              f"{args.max_files} test files (the target's own test files first), fastest first, "
              f"until their durations under coverage add up to {args.budget:.0f} s (at least one "
              "test). A "
              "constant at module or class level (a default) runs at import: its mutants run the "
              "tests of the target's `TESTS` files within the same budget. A mutant on a line no "
              "test executes survives without a run.\n")
    else:
        print("Tests per mutant (`pytest -x`), and the time of the unmutated run here:\n")
        for f, t in t_base.items():
            print(f"- `{f}`: " + ", ".join(f"`{x}`" for x in TESTS[f]) + f" ({t:.0f} s)")
        print()
    ran = sorted(dt for _, o, dt, _ in results if dt > 0)  # this run's or the earlier one's
    if ran:
        q = lambda p: ran[min(len(ran) - 1, int(p * len(ran)))]
        print(f"Wall time of the tests per mutant (pytest start-up included, {len(ran)} runs, "
              f"in parallel with other jobs on {os.cpu_count()} CPUs): median {q(0.5):.1f} s, "
              f"90th percentile {q(0.9):.1f} s, largest {ran[-1]:.1f} s; "
              f"{sum(d < 60 for d in ran)} of {len(ran)} under a minute.\n")
    print("| module | mutants | killed | survived | argued equivalent | not run | score (killed / "
          "non-equivalent run) |")
    print("|---|---|---|---|---|---|---|")
    by_file: dict[str, list] = {}
    for m, outcome, _, _ in results:
        by_file.setdefault(m.file, []).append((m, outcome))
    tot = dict(n=0, k=0, s=0, e=0, nr=0)
    for f, rs in by_file.items():
        killed = sum(o.startswith("killed") for _, o in rs)
        not_run = sum(o == "not run" for _, o in rs)
        surv = [(m, o) for m, o in rs if not o.startswith("killed") and o != "not run"]
        eq = sum((m.file, m.source, m.description) in EQUIVALENT for m, _ in surv)
        for key, v in (("n", len(rs)), ("k", killed), ("s", len(surv)), ("e", eq),
                       ("nr", not_run)):
            tot[key] += v
        print(f"| `{f}` | {len(rs)} | {killed} | {len(surv)} | {eq} | {not_run} | "
              f"{100 * killed / max(killed + len(surv) - eq, 1):.1f} % |")
    print(f"| **all** | {tot['n']} | {tot['k']} | {tot['s']} | {tot['e']} | {tot['nr']} | "
          f"**{100 * tot['k'] / max(tot['k'] + tot['s'] - tot['e'], 1):.1f} %** |")
    print("\n## Surviving mutants\n")
    print("| location | mutation | source line | outcome | equivalent because |")
    print("|---|---|---|---|---|")
    for m, outcome, _, _ in results:
        if not outcome.startswith("killed") and outcome != "not run":
            why = EQUIVALENT.get((m.file, m.source, m.description), "**not argued: a gap**")
            src = m.source.replace("|", "\\|")
            print(f"| `{m.file}:{m.lineno}` | {m.description} | `{src}` | {outcome} | {why} |")


if __name__ == "__main__":
    raise SystemExit(main())
