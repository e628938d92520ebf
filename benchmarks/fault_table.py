"""Fault table of ``rwhec-calibrate`` (issue 32): every way a run can end, as a subprocess.

Run from the repository root (about 10-15 minutes on a busy 2-core machine; writes
``benchmarks/fault_table.md``)::

    python benchmarks/fault_table.py [--work DIR] [--output FILE.md] [--only SUBSTRING ...]

Each row runs one fault as the user would meet it, ``python -m rwhec_ros.cli ...`` in a fresh
directory, and records the exit code, the first line of stderr (and how many lines it has),
whether a traceback appeared, and what is on disk afterwards: every file whole (``result.yaml``
read back by ``load_result``, the data set by ``Dataset.load`` with its ``.npz`` checksum, the
launch file compiled, the YAML parsed, the report PNG ending in its ``IEND`` chunk and the page
in ``</html>``; no temporary file left), no stale file (older than the run, or a result whose
data set fingerprint does not match the data set beside it) and, whenever pairs were gathered,
the data set present. The signals go to the process while it waits in the phase named, by the
test-only hook of :mod:`rwhec_ros.cli.run` (``RWHEC_TEST_PAUSE_PHASE``/``_FILE``). The full and
read-only directories are real ``tmpfs`` mounts (root only; the rows are skipped otherwise, and
the tests cover them with a patched writer).

The rows (and their checks) are the tests of ``test/test_cli_faults.py``, which imports this
module.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: ``config/demo.yaml``, copied beside the inputs (paths in the table relative to the row)
DEMO_YAML = "../inputs/demo.yaml"
#: The paper's data (``--paper``; default: ``shared/`` beside the repository), linked into the
#: inputs as ``paper``.
PAPER_DEFAULT = REPO / ".." / "shared" / "data" / "paper_real_world"
PHASES = ("reading", "solving", "analysing", "writing")


# ------------------------------------------------------------------------------------------------
# inputs, made once


@dataclass
class Inputs:
    """The files the faults run on, in ``root``."""

    root: Path

    def __getattr__(self, name: str) -> Path:
        return self.root / name


def make_inputs(root: Path) -> Inputs:
    """A short simulated recording (sqlite3 and MCAP), its two truncated copies, a synthetic
    problem as CSV files and as data sets (a second one, a large one with its ``.npz``, 20
    identical pairs), its true frames as the reference of ``check`` and a configuration with
    the wrong tag family."""
    import numpy as np
    import yaml

    from rwhec_ros.core.problem import Edge, Problem
    from rwhec_ros.core.synthetic import random_instance
    from rwhec_ros.data.dataset import Dataset
    from rwhec_ros.data.paper_csv import write_paper_csv
    from rwhec_ros.simulation import demo_rig, write_simulated_bag

    done = root / ".done"
    version = _code_version()
    if done.exists() and done.read_text() != version:
        # made by other code (the README rows' data set recorded a parameter since retired):
        # every input, the README's outputs included, is made again
        shutil.rmtree(root)
    root.mkdir(parents=True, exist_ok=True)
    inputs = Inputs(root)
    shutil.copy(REPO / "config" / "demo.yaml", root / "demo.yaml")
    if done.exists() and (root / "reference.yaml").exists():
        return inputs
    for storage, name in (("sqlite3", "bag"), ("mcap", "bag_mcap")):
        if not (root / name).exists():
            write_simulated_bag(root / name, demo_rig(3, 6), np.random.default_rng(0),
                                seconds=8.0, storage=storage)
        cut = root / f"trunc_{name}"
        shutil.rmtree(cut, ignore_errors=True)
        shutil.copytree(root / name, cut)
        for f in cut.iterdir():
            if f.suffix in (".db3", ".mcap"):
                with open(f, "r+b") as fh:
                    fh.truncate(f.stat().st_size // 2)
    problem, gt = random_instance(np.random.default_rng(7), 3, 3, n_per_edge=20, sigma=0.005,
                                  kappa=400.0)
    write_paper_csv(problem, root / "csv")
    Dataset.from_problem(problem).save(root / "data.yaml")
    truth = [(n, T) for names, Ts in ((problem.x_names, gt.X), (problem.y_names, gt.Y))
             for n, T in zip(names, Ts, strict=True)]  # check's reference: the true frames
    (root / "reference.yaml").write_text(yaml.safe_dump(
        {"frames": [{"name": n, "matrix": np.asarray(T).tolist()} for n, T in truth]}))
    other, _ = random_instance(np.random.default_rng(8), 3, 3, n_per_edge=20, sigma=0.005,
                               kappa=400.0)
    Dataset.from_problem(other).save(root / "other.yaml")
    big, _ = random_instance(np.random.default_rng(9), 3, 3, n_per_edge=300, sigma=0.005,
                             kappa=400.0)
    (root / "big").mkdir(exist_ok=True)
    Dataset.from_problem(big).save(root / "big" / "dataset.yaml")  # 2,700 pairs: an .npz
    (root / "big_without_npz").mkdir(exist_ok=True)
    shutil.copy(root / "big" / "dataset.yaml", root / "big_without_npz" / "dataset.yaml")
    A = np.tile(np.eye(4), (20, 1, 1))
    A[:, :3, 3] = [0.1, 0.2, 0.3]
    same = Problem(["tag_0"], ["cam_0"], [Edge.build("tag_0", "cam_0", A, np.tile(np.eye(4), (
        20, 1, 1)), sigma=np.full(20, 0.01), kappa=np.full(20, 100.0))])
    Dataset.from_problem(same).save(root / "identical.yaml")
    cfg = yaml.safe_load((REPO / "config" / "demo.yaml").read_text())
    section = next(iter(cfg.values()))["ros__parameters"]
    section["tags"]["family"] = "tag25h9"
    (root / "wrong_family.yaml").write_text(yaml.safe_dump(cfg))
    done.write_text(version)
    return inputs


def _code_version() -> str:
    """A digest of the package's sources and configuration files: the inputs made once are
    made again when it changes."""
    import hashlib

    h = hashlib.sha256()
    for f in sorted([*(REPO / "rwhec_ros").rglob("*.py"), *(REPO / "config").glob("*.yaml")]):
        h.update(f.relative_to(REPO).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest() + "\n"


# ------------------------------------------------------------------------------------------------
# running and inspecting


def cli(argv, cwd: Path, env: dict | None = None, timeout: float = 900.0):
    """``python -m rwhec_ros.cli argv`` in ``cwd``: (exit code, stdout, stderr)."""
    full = dict(os.environ, PYTHONPATH=str(REPO), **(env or {}))
    p = subprocess.run([sys.executable, "-m", "rwhec_ros.cli", *map(str, argv)], cwd=cwd,
                       env=full, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def cli_paused(argv, cwd: Path, phase: str, sig: str | None,
               during: Callable[[Path], None] | None = None, timeout: float = 900.0):
    """``cli`` that waits in ``phase`` (the test hook), then runs ``during(cwd)``, sends
    ``sig`` (``"SIGINT"``, ``"SIGTERM"``; None: none) and lets it go on."""
    marker = cwd / ".pause"
    marker.unlink(missing_ok=True)
    env = dict(os.environ, PYTHONPATH=str(REPO), RWHEC_TEST_PAUSE_PHASE=phase,
               RWHEC_TEST_PAUSE_FILE=str(marker))
    # SIGINT as a terminal delivers it: a job started in the background of a shell inherits
    # it ignored, and Python then installs no KeyboardInterrupt handler
    p = subprocess.Popen([sys.executable, "-m", "rwhec_ros.cli", *map(str, argv)], cwd=cwd,
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.monotonic()
    while not marker.exists() and p.poll() is None and time.monotonic() - t0 < timeout:
        time.sleep(0.05)
    reached = marker.exists()
    if reached:
        if during is not None:
            during(cwd)
        if sig is not None:
            p.send_signal(getattr(signal, sig))
        else:
            marker.unlink()
    out, err = p.communicate(timeout=timeout)
    marker.unlink(missing_ok=True)
    return p.returncode, out, err, reached


@dataclass
class Disk:
    """What is in an output directory after a run."""

    files: list[str] = field(default_factory=list)
    broken: list[str] = field(default_factory=list)  # truncated, unreadable or temporary
    stale: list[str] = field(default_factory=list)  # older than the run, or mixed up
    pairs: int = 0  # in the data set (0: none)

    def words(self) -> str:
        if not self.files:
            return "nothing"
        names = [f"{f} ({self.pairs} pairs)" if f == "dataset.yaml" else f for f in self.files]
        return ", ".join(names)


def whole(path: Path) -> str:
    """Why ``path`` is not a whole output file, or ``""``."""
    import yaml

    from rwhec_ros.data.dataset import Dataset
    from rwhec_ros.data.results import load_result

    try:
        if path.name.startswith(".") or path.suffix == ".tmp":
            return "temporary file left"
        if path.name == "result.yaml" or path.name.endswith(".result.yaml"):
            load_result(path)
        elif path.name == "dataset.yaml":
            Dataset.load(path)
        elif path.suffix == ".py":
            compile(path.read_text(), str(path), "exec")
        elif path.suffix in (".yaml", ".xacro"):
            yaml.safe_load(path.read_text()) if path.suffix == ".yaml" else None
            if path.suffix == ".xacro" and not path.read_text().rstrip().endswith("</robot>"):
                return "not ended"
        elif path.suffix == ".png":
            data = path.read_bytes()
            if not (data.startswith(b"\x89PNG") and data[-8:-4] == b"IEND"):
                return "not a whole PNG"
        elif path.suffix == ".html" and not path.read_text().rstrip().endswith("</html>"):
            return "not ended"
    except Exception as exc:  # noqa: BLE001 - what is wrong with the file, in the table
        return f"{type(exc).__name__}: {str(exc)[:80]}"
    return ""


def inspect(directory: Path, started: float) -> Disk:
    """The files of ``directory`` (and of any rescue directory beside the run), checked."""
    import yaml

    from rwhec_ros.data.dataset import Dataset
    from rwhec_ros.data.fingerprint import fingerprint_mismatch

    disk = Disk()
    if not directory.is_dir():
        return disk
    old, new = [], []
    for path in sorted(directory.iterdir()):
        if path.is_dir():
            continue
        disk.files.append(path.name)
        why = whole(path)
        if why:
            disk.broken.append(f"{path.name}: {why}")
        (old if path.stat().st_mtime < started else new).append(path.name)
    if old and new:  # files of an earlier run beside those of this one (a refused run: old only)
        disk.stale += [f"{name}: from an earlier run" for name in old]
    data = directory / "dataset.yaml"
    if data.name in disk.files and not any(b.startswith("dataset") for b in disk.broken):
        dataset = Dataset.load(data)
        disk.pairs = dataset.n_pairs
        result = directory / "result.yaml"
        if result.exists() and not any(b.startswith("result") for b in disk.broken):
            recorded = (yaml.safe_load(result.read_text()) or {}).get("dataset_fingerprint")
            if isinstance(recorded, dict) and fingerprint_mismatch(recorded, dataset):
                disk.stale.append("result.yaml: of another data set")
    return disk


# ------------------------------------------------------------------------------------------------
# the faults


@dataclass
class Fault:
    """One row: ``argv(inputs, row_dir)`` run in ``row_dir``; the output directory
    ``row_dir/out``. ``phase``/``sig``: the signal in that phase; ``gathered``: pairs were
    gathered, so a data set must be on disk; ``setup``/``during``/``cleanup`` prepare the
    row, act while it waits, and undo mounts; ``check(stdout, stderr)`` more words to find."""

    name: str
    argv: Callable[[Inputs, Path], list]
    expect: int
    gathered: bool = False
    phase: str | None = None
    sig: str | None = None
    setup: Callable[[Inputs, Path], None] | None = None
    during: Callable[[Path], None] | None = None
    cleanup: Callable[[Path], None] | None = None
    check: Callable[[str, str], str] | None = None
    root_only: bool = False
    out: str = "out"
    paper: bool = False


@dataclass
class Row:
    fault: Fault
    code: int | None
    first: str
    lines: int
    traceback: bool
    disk: Disk
    problems: list[str]
    seconds: float

    @property
    def passed(self) -> bool:
        return not self.problems


def _bag(i: Inputs, d: Path) -> list:
    return ["bag", i.bag, "--config", DEMO_YAML, "-o", d / "out", "-q"]


def _csv(i: Inputs, d: Path) -> list:
    return ["csv", i.csv, "-o", d / "out", "-q"]


def _check(i: Inputs, d: Path) -> list:
    return ["check", i.root / "data.yaml", "--reference", i.root / "reference.yaml", "-o",
            d / "out", "-q"]


def _dataset(i: Inputs, d: Path) -> list:
    return ["dataset", i.root / "data.yaml", "-o", d / "out", "-q"]


def _mount(size: str, ro: bool = False) -> Callable[[Inputs, Path], None]:
    def setup(i: Inputs, d: Path) -> None:
        (d / "mnt").mkdir(parents=True, exist_ok=True)
        opts = f"size={size}" + (",ro" if ro else "")
        subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(d / "mnt")],
                       check=True, capture_output=True)
    return setup


def _umount(d: Path) -> None:
    subprocess.run(["umount", str(d / "mnt")], capture_output=True)


def _fill(d: Path) -> None:
    """Fill the tmpfs ``d/mnt`` (outside the output directory) to the last byte."""
    try:
        with open(d / "mnt" / "filler", "wb", buffering=0) as fh:
            while True:
                fh.write(b"\0" * 4096)
    except OSError:  # ENOSPC: full
        pass


def _run_first(argv_of: Callable[[Inputs, Path], list]) -> Callable[[Inputs, Path], None]:
    """Setup: run a command once before the row (an earlier run)."""
    def setup(i: Inputs, d: Path) -> None:
        code, out, err = cli(argv_of(i, d), d)
        if code not in (0, 4):
            raise RuntimeError(f"setup of {argv_of(i, d)} failed ({code}): {err}")
        time.sleep(1.1)  # file times: an earlier run is older than the row's start
    return setup


def _mixed(i: Inputs, d: Path) -> None:
    """``a/``: a result of data.yaml; ``b/``: of other.yaml."""
    for name, data in (("a", "data.yaml"), ("b", "other.yaml")):
        code, _, err = cli(["dataset", i.root / data, "-o", d / name, "-q"], d)
        if code != 0:
            raise RuntimeError(err)


def _swap(i: Inputs, d: Path) -> None:
    _mixed(i, d)
    shutil.copy(d / "b" / "dataset.yaml", d / "a" / "dataset.yaml")


def _older(i: Inputs, d: Path) -> None:
    import yaml

    _mixed(i, d)
    doc = yaml.safe_load((d / "a" / "result.yaml").read_text())
    doc.pop("dataset_fingerprint")
    (d / "a" / "result.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))


def _cut_result(i: Inputs, d: Path) -> None:
    _mixed(i, d)
    text = (d / "a" / "result.yaml").read_text()
    cut = text[: text.index("\n", int(0.7 * len(text))) + 1]
    (d / "a" / "result.yaml").write_text(cut)


def _no(words: str, where: str = "both") -> Callable[[str, str], str]:
    def check(stdout: str, stderr: str) -> str:
        text = {"out": stdout, "err": stderr}.get(where, stdout + stderr)
        return f"says {words!r}" if words in text else ""
    return check


def _has(words: str) -> Callable[[str, str], str]:
    def check(stdout: str, stderr: str) -> str:
        return "" if words in stdout + stderr else f"does not say {words!r}"
    return check


def faults() -> list[Fault]:
    """Every row of the table."""
    rows = []
    for cmd, argv in (("bag", _bag), ("csv", _csv), ("dataset", _dataset), ("check", _check)):
        for sig in ("SIGINT", "SIGTERM"):
            for phase in PHASES:
                rows.append(Fault(
                    f"{cmd}: {sig} while {phase}", argv, 130 if sig == "SIGINT" else 143,
                    gathered=phase != "reading" or cmd == "bag", phase=phase, sig=sig,
                    check=_has(f"interrupted ({sig}) while {phase}")))
    rows += [
        Fault("bag: -o on a read-only file system", lambda i, d: [
            "bag", i.bag, "--config", DEMO_YAML, "-o", d / "mnt" / "out", "-q"], 2,
            setup=_mount("1m", ro=True), cleanup=_umount, root_only=True, out="mnt/out",
            check=_has("read-only file system")),
        Fault("bag: -o on a full file system (200 KiB)", lambda i, d: [
            "bag", i.bag, "--config", DEMO_YAML, "-o", d / "mnt" / "out", "-q"], 2,
            setup=_mount("200k"), cleanup=_umount, root_only=True, out="mnt/out",
            check=_has("free")),
        Fault("bag: the disk fills while solving", lambda i, d: [
            "bag", i.bag, "--config", DEMO_YAML, "-o", d / "mnt" / "out", "-q"], 2,
            gathered=True, phase="solving", setup=_mount("2m"), during=_fill, cleanup=_umount,
            root_only=True, out="mnt/out", check=_has("resume with: ")),
        Fault("bag: truncated sqlite3 recording", lambda i, d: [
            "bag", i.trunc_bag, "--config", DEMO_YAML, "-o", d / "out", "-q"], 2,
            check=_has("ros2 bag reindex")),
        Fault("bag: truncated MCAP recording", lambda i, d: [
            "bag", i.trunc_bag_mcap, "--config", DEMO_YAML, "-o", d / "out", "-q"], 2,
            check=_has("ros2 bag reindex")),
        Fault("bag: wrong tag family", lambda i, d: [
            "bag", i.bag, "--config", i.root / "wrong_family.yaml", "-o", d / "out", "-q"], 3,
            check=_has("tags.family=tag25h9")),
        Fault("report: result beside another data set", lambda i, d: [
            "report", d / "a" / "result.yaml", "--dataset", d / "b" / "dataset.yaml", "-o",
            d / "out"], 2, setup=_mixed, check=_has("was not solved from")),
        Fault("dataset: data set replaced beside its result", lambda i, d: [
            "dataset", d / "a" / "dataset.yaml", "-o", d / "out", "-q"], 2, setup=_swap,
            check=_has("was not solved from")),
        Fault("report: an older result without fingerprint", lambda i, d: [
            "report", d / "a" / "result.yaml", "-o", d / "out"], 0, setup=_older,
            check=_has("records no data set fingerprint")),
        Fault("report: truncated result.yaml", lambda i, d: [
            "report", d / "a" / "result.yaml", "-o", d / "out"], 2, setup=_cut_result,
            check=_no("KeyError")),
        Fault("dataset: --force over a larger earlier run (.npz, report)", lambda i, d: [
            *_dataset(i, d), "--force"], 0,
              gathered=True, setup=_run_first(lambda i, d: [
                  "dataset", i.root / "big" / "dataset.yaml", "-o", d / "out", "--report",
                  "-q"]),
              check=None),
        Fault("dataset: --min-pairs above every edge", lambda i, d: [
            "dataset", i.root / "data.yaml", "-o", d / "out", "--min-pairs", "99", "-q"], 3,
            gathered=True, check=_has("lower --min-pairs to 20")),
        Fault("dataset: 20 identical pairs (solver failure)", lambda i, d: [
            "dataset", i.root / "identical.yaml", "-o", d / "out", "-q"], 4, gathered=True,
            check=lambda o, e: _no("--mode sdp", "out")(o, e) or _no("Try another")(o, e)),
        Fault("check: --reference among the files -o replaces", lambda i, d: [
            "check", i.root / "data.yaml", "--reference", d / "out" / "result.yaml", "-o",
            d / "out", "--force", "-q"], 2, setup=_run_first(lambda i, d: [
                "dataset", i.root / "data.yaml", "-o", d / "out", "-q"]),
            check=_has("whose outputs the check replaces")),
        Fault("dataset: its .npz missing", lambda i, d: [
            "dataset", i.root / "big_without_npz" / "dataset.yaml", "-o", d / "out", "-q"], 2,
            check=_no("[Errno")),
    ]
    # the README's recipes, each run twice (the second run: refused in one line, or --force)
    readme = [
        ("README: demo --bag demo_bag", lambda i, d: ["demo", "--bag", d / "demo_bag"], 2,
         False),
        ("README: bag demo_bag -o bag_out", lambda i, d: [
            "bag", d / "demo_bag", "--config", DEMO_YAML, "-o", d / "out"], 2, False),
        ("README: bag demo_bag -o bag_out --force", lambda i, d: [
            "bag", d / "demo_bag", "--config", DEMO_YAML, "-o", d / "out", "--force"], 0, False),
        ("README: csv paper -o fast", lambda i, d: ["csv", i.paper, "-o", d / "out"], 2, True),
        ("README: report fast/result.yaml", lambda i, d: ["report", d / "out" / "result.yaml"],
         2, True),
        ("README: demo -o demo_out --report", lambda i, d: [
            "demo", "-o", d / "out", "--report"], 2, False),
        ("README: dataset demo_out/dataset.yaml -o demo_again", lambda i, d: [
            "dataset", d / "demo" / "dataset.yaml", "-o", d / "out"], 2, False),
    ]
    for name, argv, code, paper in readme:
        rows.append(Fault(name + " (again)", argv, code, gathered=code == 0, paper=paper,
                          setup=_readme_setup(name)))
    return rows


def _readme_setup(name: str) -> Callable[[Inputs, Path], None]:
    """The runs of the README before the row: the recipe itself (and what it needs), run once
    into ``inputs/readme/`` and copied into the row's directory (the rows share them)."""
    def setup(i: Inputs, d: Path) -> None:
        cache = i.root / "readme"
        cache.mkdir(exist_ok=True)

        def once(target: str, argv: list) -> None:
            if not (cache / target).exists():
                code, _, err = cli(argv, cache)
                if code not in (0, 4):
                    raise RuntimeError(f"README step {argv} failed ({code}): {err}")
            if not (d / target).exists():
                shutil.copytree(cache / target, d / target, symlinks=True)

        if "demo_bag" in name:  # the simulated recording of the README (24 s)
            once("demo_bag", ["demo", "--bag", "demo_bag"])
        if "bag demo_bag" in name:
            once("demo_bag", ["demo", "--bag", "demo_bag"])
            once("bag_out", ["bag", "demo_bag", "--config", i.root / "demo.yaml", "-o",
                             "bag_out", "-q"])
            shutil.move(d / "bag_out", d / "out")
        if "csv paper" in name or "report fast" in name:
            once("fast", ["csv", "../paper", "-o", "fast", "-q"])
            shutil.move(d / "fast", d / "out")
        if "report fast" in name:
            code, _, err = cli(["report", d / "out" / "result.yaml"], d)
            if code != 0:
                raise RuntimeError(err)
        if "demo -o" in name:
            once("demo_out", ["demo", "-o", "demo_out", "--report", "-q"])
            shutil.move(d / "demo_out", d / "out")
        if "demo_again" in name:
            once("demo_out", ["demo", "-o", "demo_out", "--report", "-q"])
            shutil.move(d / "demo_out", d / "demo")
            code, _, err = cli(["dataset", d / "demo" / "dataset.yaml", "-o", d / "out", "-q"],
                               d)
            if code not in (0, 4):
                raise RuntimeError(err)
        time.sleep(1.1)
    return setup


def run_fault(fault: Fault, inputs: Inputs, work: Path) -> Row | None:
    """Run one row in a fresh directory under ``work``; None when it cannot run here (root
    needed for a mount, the paper's data absent)."""
    if fault.root_only and os.geteuid() != 0:
        return None
    if fault.paper and not inputs.paper.is_dir():
        return None
    d = work / "".join(ch if ch.isalnum() else "_" for ch in fault.name).strip("_")
    if (d / "mnt").is_dir():
        _umount(d)
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    try:
        if fault.setup is not None:
            fault.setup(inputs, d)
        started = time.time() - 0.01
        t0 = time.monotonic()
        # paths relative to the row's directory: the table shows what a user would type
        argv = [os.path.relpath(a, d) if isinstance(a, Path) else a
                for a in fault.argv(inputs, d)]
        if fault.phase is not None:
            code, out, err, reached = cli_paused(argv, d, fault.phase, fault.sig, fault.during)
        else:
            (code, out, err), reached = cli(argv, d), True
        seconds = time.monotonic() - t0
        disk = inspect(d / fault.out, started)
    finally:
        if fault.cleanup is not None:
            fault.cleanup(d)
    lines = err.splitlines()
    problems = []
    if not reached:
        problems.append(f"never reached {fault.phase}")
    if code != fault.expect:
        problems.append(f"exit {code}, expected {fault.expect}")
    if "Traceback" in err or "Traceback" in out:
        problems.append("traceback")
    if code not in (0, 4) and len(lines) != 1:  # 0, 4: a result, the verdict on stdout
        problems.append(f"{len(lines)} stderr lines")
    problems += disk.broken + disk.stale
    if fault.gathered and not disk.pairs:
        problems.append("pairs gathered, no data set kept")
    if fault.check is not None:
        extra = fault.check(out, err)
        if extra:
            problems.append(extra)
    return Row(fault, code, lines[0] if lines else "", len(lines), "Traceback" in err, disk,
               problems, seconds)


def table(rows: list[Row], skipped: list[str]) -> str:
    """The Markdown table and its counts."""
    out = ["| fault | exit | stderr (first line; lines) | on disk afterwards | verdict |",
           "|---|---|---|---|---|"]
    for r in rows:
        first = r.first.replace("|", "\\|")
        if len(first) > 300:
            first = first[:297] + "..."
        out.append(f"| {r.fault.name} | {r.code} | {first or '(none)'}; {r.lines} | "
                   f"{r.disk.words()} | {'ok' if r.passed else '; '.join(r.problems)} |")
    tracebacks = sum(r.traceback for r in rows)
    broken = sum(len(r.disk.broken) + len(r.disk.stale) for r in rows)
    lost = sum(r.fault.gathered and not r.disk.pairs for r in rows)
    out += ["", f"{len(rows)} faults run, {sum(r.passed for r in rows)} as expected; "
            f"tracebacks: {tracebacks}; truncated or stale files: {broken}; runs that gathered "
            f"pairs and kept none: {lost}."]
    if skipped:
        out.append(f"Not run here: {', '.join(skipped)}.")
    return "\n".join(out)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path("/tmp") / "rwhec_fault_table")
    parser.add_argument("--output", type=Path, default=REPO / "benchmarks" / "fault_table.md")
    parser.add_argument("--only", nargs="*", default=None, help="rows whose name contains one")
    parser.add_argument("--paper", type=Path, default=PAPER_DEFAULT,
                        help="the paper's CSV data (rows of the README's csv recipes)")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO))
    t0 = time.monotonic()
    inputs = make_inputs(args.work / "inputs")
    if args.paper.is_dir() and not inputs.paper.exists():
        inputs.paper.symlink_to(args.paper.resolve())
    rows, skipped = [], []
    for fault in faults():
        if args.only and not any(s in fault.name for s in args.only):
            continue
        row = run_fault(fault, inputs, args.work)
        if row is None:
            skipped.append(fault.name)
            continue
        rows.append(row)
        print(f"{fault.name}: exit {row.code}, {'ok' if row.passed else row.problems}",
              file=sys.stderr)
    load = os.getloadavg()
    text = ("# Fault table of rwhec-calibrate (issue 32)\n\n"
            "Written by `python benchmarks/fault_table.py` (each fault a subprocess; the "
            "signal rows wait in the phase named by the test-only hook `RWHEC_TEST_PAUSE_PHASE`"
            "). The data: an 8 s simulated recording (3 cameras, 6 tags), a synthetic 3 x 3 "
            "problem (20 pairs per edge) as CSV files and data set, the README's own recipes."
            f" {time.monotonic() - t0:.0f} s in all, load average {load[0]:.1f} (2 shared "
            "cores).\n\n" + table(rows, skipped) + "\n")
    if not args.only:
        args.output.write_text(text)
    print(text)
    return 0 if all(r.passed for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
