"""Nothing lost, nothing mixed up (issue 32): every row of ``benchmarks/fault_table.py`` as a
test (a subprocess each: signals in every phase, full and read-only directories, damaged bags
and results, mismatched files, the README's recipes run again), and the pieces in process:
atomic writes under a failing writer, the fingerprint, the session's unsaved pairs at shutdown,
the words of the errors, the report's drawing of rejected edges."""

from __future__ import annotations

import errno
import io
import os
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rwhec_ros.cli import EXIT_BAD_INPUT, EXIT_NO_SOLUTION, EXIT_OK, main
from rwhec_ros.data.dataset import Dataset

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCH))

import fault_table as ft  # noqa: E402

FAULTS = {f.name: f for f in ft.faults()}


def run(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], stdout=out, stderr=err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def fault_inputs(tmp_path_factory):
    pytest.importorskip("rosbags.rosbag2")
    work = tmp_path_factory.mktemp("faults")
    inputs = ft.make_inputs(work / "inputs")
    paper = ft.PAPER_DEFAULT
    if paper.is_dir() and not inputs.paper.exists():
        inputs.paper.symlink_to(paper.resolve())
    return inputs, work


@pytest.mark.slow
@pytest.mark.parametrize("name", list(FAULTS))
def test_fault_table_row(fault_inputs, name):
    """One row: the exit code documented, one stderr line without traceback, every file on
    disk whole and of this run, and the data set there whenever pairs were gathered."""
    inputs, work = fault_inputs
    row = ft.run_fault(FAULTS[name], inputs, work)
    if row is None:
        pytest.skip("needs root (a tmpfs mount) or the paper's data")
    assert row.passed, (row.problems, row.first)


@pytest.mark.slow
def test_a_bag_damaged_part_way_keeps_the_pairs_read(fault_inputs, tmp_path, monkeypatch):
    """A storage file that opens but fails part-way (rosbags raises while reading): one line
    with the reason and the repair, and the pairs read up to the damage kept."""
    import rwhec_ros.data.rosbag as rosbag

    inputs, _ = fault_inputs
    real = rosbag.read_messages

    def damaged(path, topics, **kw):
        for i, m in enumerate(real(path, topics, **kw)):
            if i == 500:
                raise ValueError(rosbag.damaged_bag_words(
                    path, RuntimeError("database disk image is malformed"), i, 720))
            yield m

    monkeypatch.setattr(rosbag, "read_messages", damaged)
    out = tmp_path / "out"
    code, stdout, stderr = run(["bag", inputs.bag, "--config", ft.REPO / "config" / "demo.yaml",
                                "-o", out, "-q"])
    assert code == EXIT_BAD_INPUT and len(stderr.splitlines()) == 1, stderr
    assert "500 of 720 messages were read before the damage" in stderr
    assert "ros2 bag reindex" in stderr and "resume with: rwhec-calibrate dataset" in stderr
    assert Dataset.load(out / "dataset.yaml").n_pairs > 0


# --- the checks of the table can fail -----------------------------------------------------------


def test_the_inspection_finds_truncated_stale_and_temporary_files(tmp_path):
    from rwhec_ros.core.synthetic import random_instance

    problem, _ = random_instance(np.random.default_rng(1), 2, 2, n_per_edge=6)
    Dataset.from_problem(problem).save(tmp_path / "dataset.yaml")
    text = (tmp_path / "dataset.yaml").read_text()
    (tmp_path / "result.yaml").write_text("certified: true\n")
    (tmp_path / ".result.yaml.x1.tmp").write_text("")
    started = os.stat(tmp_path / "dataset.yaml").st_mtime + 0.5  # the data set is older
    os.utime(tmp_path / "result.yaml", (started + 1, started + 1))  # this run's
    disk = ft.inspect(tmp_path, started)
    assert any(b.startswith("result.yaml") for b in disk.broken)
    assert any("temporary" in b for b in disk.broken)
    assert any(s.startswith("dataset.yaml") for s in disk.stale)
    (tmp_path / "dataset.yaml").write_text(text[: len(text) // 2])
    assert any(b.startswith("dataset.yaml") for b in ft.inspect(tmp_path, 0.0).broken)


# --- atomic writes ------------------------------------------------------------------------------


def test_a_failing_write_leaves_the_earlier_file_and_no_temporary(tmp_path, monkeypatch):
    import rwhec_ros.data.atomic as atomic

    target = tmp_path / "result.yaml"
    atomic.atomic_write_text(target, "old: 1\n")
    real = os.fsync

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError):
        atomic.atomic_write_text(target, "new: 2\n" * 1000)
    monkeypatch.setattr(os, "fsync", real)
    assert target.read_text() == "old: 1\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.yaml"]


def test_an_interrupt_while_staging_leaves_every_file_as_it_was(tmp_path, monkeypatch):
    import rwhec_ros.data.atomic as atomic

    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("A0")
    b.write_text("B0")
    real = atomic._write_temp
    calls = []

    def second_interrupted(path, data):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(path, data)

    monkeypatch.setattr(atomic, "_write_temp", second_interrupted)
    with pytest.raises(KeyboardInterrupt), atomic.StagedFiles() as staged:
        staged.stage(a, "A1")
        staged.stage(b, "B1")
        staged.commit()
    assert (a.read_text(), b.read_text()) == ("A0", "B0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


@pytest.mark.parametrize("code, words", [(errno.ENOSPC, "no space left on device"),
                                         (errno.EROFS, "read-only file system")])
def test_a_failed_write_after_the_solve_keeps_the_data_set(tmp_path, monkeypatch, code, words):
    """The writer fails for result.yaml (full disk, read-only): one line with the reason, the
    data set written before the solve stays, with the command that resumes it; no verdict is
    printed as if the files were there."""
    import rwhec_ros.data.atomic as atomic

    data = _synthetic(tmp_path)
    real = atomic._write_temp

    def failing(path, payload):
        if path.name != "dataset.yaml":
            raise OSError(code, os.strerror(code))
        return real(path, payload)

    monkeypatch.setattr(atomic, "_write_temp", failing)
    out = tmp_path / "out"
    status, stdout, stderr = run(["dataset", data, "-o", out, "-q"])
    assert status == EXIT_BAD_INPUT and stdout == ""
    assert len(stderr.splitlines()) == 1 and "Traceback" not in stderr
    assert f"cannot write the outputs into {out}: {words}" in stderr
    assert f"resume with: rwhec-calibrate dataset {out / 'dataset.yaml'} -o {out} --force" \
        in stderr
    assert sorted(p.name for p in out.iterdir()) == ["dataset.yaml"]
    assert Dataset.load(out / "dataset.yaml").n_pairs == 4 * 8


def test_force_replaces_the_whole_set_of_an_earlier_run(tmp_path):
    from rwhec_ros.core.synthetic import random_instance

    big, _ = random_instance(np.random.default_rng(3), 2, 2, n_per_edge=600)
    Dataset.from_problem(big).save(tmp_path / "big.yaml")
    out = tmp_path / "out"
    assert run(["dataset", tmp_path / "big.yaml", "-o", out, "-q", "--report"])[0] == EXIT_OK
    assert (out / "dataset.npz").is_file() and (out / "report.png").is_file()
    code, stdout, stderr = run(["dataset", _synthetic(tmp_path), "-o", out, "--force", "-q"])
    assert code == EXIT_OK, stderr
    assert sorted(p.name for p in out.iterdir()) == [
        "calibration.urdf.xacro", "dataset.yaml", "frames.yaml", "result.yaml",
        "static_transforms.launch.py"]


def test_outputs_are_checked_before_any_work(tmp_path, monkeypatch):
    import rwhec_ros.data.atomic as atomic

    monkeypatch.setattr(atomic, "free_bytes", lambda path: 100 * 1024)
    code, _, stderr = run(["dataset", _synthetic(tmp_path), "-o", tmp_path / "out", "-q"])
    assert code == EXIT_BAD_INPUT and len(stderr.splitlines()) == 1
    assert "-o/--output: cannot write the outputs into" in stderr
    assert "only 100 KiB free on its file system, the outputs need about 256 KiB" in stderr
    assert not (tmp_path / "out").exists()


# --- the fingerprint ----------------------------------------------------------------------------


def test_the_fingerprint_is_of_the_pairs_not_of_the_file(tmp_path):
    from rwhec_ros.data.fingerprint import dataset_fingerprint, fingerprint_mismatch

    data = Dataset.load(_synthetic(tmp_path))
    fp = dataset_fingerprint(data)
    assert fp["total"] == 32 and len(fp["pairs"]) == 4
    data.save(tmp_path / "npz.yaml", arrays="npz")
    assert dataset_fingerprint(Dataset.load(tmp_path / "npz.yaml")) == fp  # inline or .npz
    assert fingerprint_mismatch(fp, data) == ""
    e = data.edges[0]
    e.B[0, 0, 3] += 1e-9  # one coordinate of one pair
    assert "the same counts, other values" in fingerprint_mismatch(fp, data)


def test_report_refuses_another_data_set_and_warns_for_an_older_result(tmp_path):
    data = _synthetic(tmp_path)
    assert run(["dataset", data, "-o", tmp_path / "a", "-q"])[0] == EXIT_OK
    from rwhec_ros.core.synthetic import random_instance

    other, _ = random_instance(np.random.default_rng(12), 2, 2, n_per_edge=9)
    Dataset.from_problem(other).save(tmp_path / "other.yaml")
    result = tmp_path / "a" / "result.yaml"
    code, _, stderr = run(["report", result, "--dataset", tmp_path / "other.yaml", "-o",
                           tmp_path / "r"])
    assert code == EXIT_BAD_INPUT and len(stderr.splitlines()) == 1
    assert f"{result} was not solved from {tmp_path / 'other.yaml'}: the result was solved " \
        "from 32 pairs on 4 edges, the data set has 36 pairs on 4 edges" in stderr
    doc = yaml.safe_load(result.read_text())
    assert doc["dataset_fingerprint"]["total"] == 32
    doc.pop("dataset_fingerprint")
    result.write_text(yaml.safe_dump(doc, sort_keys=False))
    code, _, stderr = run(["report", result, "-o", tmp_path / "r"])
    assert code == EXIT_OK and stderr.startswith("rwhec-calibrate report: warning: ")
    assert "records no data set fingerprint" in stderr and len(stderr.splitlines()) == 1


def test_a_truncated_result_is_named_not_a_traceback(tmp_path):
    from rwhec_ros.data.results import load_result

    data = _synthetic(tmp_path)
    assert run(["dataset", data, "-o", tmp_path / "a", "-q"])[0] == EXIT_OK
    result = tmp_path / "a" / "result.yaml"
    text = result.read_text()
    accepted = []
    for i in range(1, 40):  # cut at every 2.5 % (at a line end: the YAML still parses)
        cut = text[: text.index("\n", int(i / 40 * len(text))) + 1]
        result.write_text(cut)
        try:
            load_result(result)
            accepted.append(i)
        except ValueError as exc:
            assert str(exc).startswith(f"{result}:")  # the file named (and the line)
    assert accepted == []
    code, _, stderr = run(["report", result, "-o", tmp_path / "r"])
    assert code == EXIT_BAD_INPUT and len(stderr.splitlines()) == 1
    assert "Traceback" not in stderr and "KeyError" not in stderr


# --- the session at shutdown --------------------------------------------------------------------


class _Log:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(("info", text))

    def error(self, text):
        self.lines.append(("error", text))


def test_the_node_shutdown_writes_unsaved_pairs_once(tmp_path):
    from rwhec_ros.cli import demo_parameters
    from rwhec_ros.config import CalibratorConfig
    from rwhec_ros.session import CalibrationSession
    from rwhec_ros.session.responses import save_on_shutdown
    from rwhec_ros.simulation import demo_rig, simulated_stream

    rig = demo_rig(2, 3)
    config = CalibratorConfig.from_parameters(demo_parameters(rig))
    session = CalibrationSession(config, output_root=tmp_path)
    log = _Log()
    assert save_on_shutdown(session, log) is None and log.lines == []  # nothing gathered
    for cam in rig.cameras:
        session.set_camera_info(cam, rig.intrinsics[cam])
    for stamp, cam, data in simulated_stream(rig, np.random.default_rng(0), seconds=4.0):
        if cam is None:
            session.add_pose(stamp, data, source="world")
        else:
            session.add_image(cam, stamp, data)
    n = session.unsaved_pairs()
    assert n > 0
    path = save_on_shutdown(session, log)
    assert path is not None and Dataset.load(path).n_pairs == n
    assert log.lines == [("info", f"shutdown: {n} unsaved pairs written: {Path(path).resolve()} "
                                  f"(solve them with rwhec-calibrate dataset "
                                  f"{Path(path).resolve()})")]
    assert session.unsaved_pairs() == 0 and save_on_shutdown(session, log) is None
    session.save_dataset(tmp_path / "manual.yaml")  # a ~/save_dataset: nothing left unsaved
    assert session.unsaved_pairs() == 0
    session.close()


def test_a_failed_shutdown_write_is_logged_not_raised(tmp_path, monkeypatch):
    from rwhec_ros.session.responses import save_on_shutdown

    class Broken:
        def unsaved_pairs(self):
            return 5

        def save_dataset(self):
            raise OSError(errno.EROFS, "Read-only file system")

    log = _Log()
    assert save_on_shutdown(Broken(), log) is None
    assert log.lines[0][0] == "error" and "could not be written" in log.lines[0][1]


# --- words --------------------------------------------------------------------------------------


def test_a_solver_failure_names_what_ran_and_only_what_is_left():
    from rwhec_ros.core.problem import Edge, Problem
    from rwhec_ros.session.solving import solve_and_assess

    A = np.tile(np.eye(4), (20, 1, 1))
    A[:, :3, 3] = [0.1, 0.2, 0.3]
    same = Problem(["tag_0"], ["cam_0"], [Edge.build("tag_0", "cam_0", A, np.tile(np.eye(4), (
        20, 1, 1)), sigma=np.full(20, 0.01), kappa=np.full(20, 100.0))])
    for mode in ("fast", "sdp"):
        solved = solve_and_assess(same, mode=mode, accuracy=None)
        first = solved.verdict.messages()[0]
        if solved.result.certificate.status.value != "solver_failed":
            pytest.skip(f"the solver did not fail on identical pairs in mode {mode}")
        assert "--mode sdp" not in first and "Try another solver" not in first, first
        assert "verbose=True" not in first and "left to try: " in first
        what = "its SDP fallback (Clarabel)" if mode == "fast" else "the SDP solver (Clarabel)"
        assert what in first, first


def test_exact_identical_pairs_raise_no_numpy_warning(tmp_path):
    """20 identical pairs (exact data, nothing determined): the residual cost at rounding level
    once came out a hair below zero, its square root was NaN and numpy's "invalid value
    encountered in sqrt" reached the user as a note (``benchmarks/fault_table.md``)."""
    from rwhec_ros.core.problem import Edge, Problem

    A = np.tile(np.eye(4), (20, 1, 1))
    A[:, :3, 3] = [0.1, 0.2, 0.3]
    same = Problem(["tag_0"], ["cam_0"], [Edge.build("tag_0", "cam_0", A, np.tile(np.eye(4), (
        20, 1, 1)), sigma=np.full(20, 0.01), kappa=np.full(20, 100.0))])
    path = Dataset.from_problem(same).save(tmp_path / "same.yaml")
    code, stdout, stderr = run(["dataset", path, "-o", tmp_path / "o", "-q"])
    assert stdout.startswith("UNUSABLE") and "invalid value" not in stderr + stdout, stderr
    doc = yaml.safe_load((tmp_path / "o" / "result.yaml").read_text())
    assert doc["uncertainty"]["variance_factor"] >= 0.0


def test_errors_name_the_option_and_its_value(tmp_path):
    data = _synthetic(tmp_path)
    code, stdout, stderr = run(["dataset", data, "-o", tmp_path / "o", "--min-pairs", "9",
                                "-q"])
    assert code == EXIT_NO_SOLUTION and stdout == "" and len(stderr.splitlines()) == 1
    assert "no edge has 9 pairs (--min-pairs=9)" in stderr and "to_problem" not in stderr
    assert "lower --min-pairs to 8 or record more" in stderr
    (tmp_path / "o2").mkdir()
    Dataset.load(_big(tmp_path)).save(tmp_path / "o2" / "dataset.yaml", arrays="npz")
    (tmp_path / "o2" / "dataset.npz").unlink()
    code, _, stderr = run(["dataset", tmp_path / "o2" / "dataset.yaml", "-q"])
    assert code == EXIT_BAD_INPUT and "[Errno" not in stderr
    assert "cannot read dataset.npz beside it (no such file or directory)" in stderr


def test_demo_bag_is_refused_in_one_line_when_it_exists(tmp_path):
    (tmp_path / "demo_bag").mkdir()
    code, _, stderr = run(["demo", "--bag", tmp_path / "demo_bag"])
    assert code == EXIT_BAD_INPUT and len(stderr.splitlines()) == 1
    assert "already exists (a recording is never overwritten): give another directory, or " \
        "--force to replace it" in stderr


def test_the_report_draws_a_rejected_edge_as_rejected():
    from matplotlib.figure import Figure

    from rwhec_ros.report.figure import _identifiability

    ax = Figure().add_subplot()
    _identifiability(ax, None, ["tag_0", "tag_1"], ["cam_0"],
                     {"(tag_1, cam_0)": "outlier rejection: all 4 pairs rejected"})
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "rejected (outlier rejection: every pair)" in labels
    assert "not observed" in labels  # (tag_0, cam_0): no pair at all


def test_the_ranked_edges_label_every_tick():
    from matplotlib.figure import Figure

    from rwhec_ros.core.verdict import FitStatistics
    from rwhec_ros.report.figure import _ranked

    class E:  # an edge of the fit, as _ranked reads it
        def __init__(self, i, r):
            self.x, self.y, self.pairs, self.flagged = f"tag_{i}", "cam_0", 5, False
            self.ratio = self.ratio_translation = r
            self.ratio_rotation = r * 0.9
            self.rms_translation_m, self.rms_rotation_deg = 1e-3, 0.1

    fit = FitStatistics.__new__(FitStatistics)
    object.__setattr__(fit, "edges", [E(i, r) for i, r in enumerate((0.8, 1.1, 1.6, 2.3))])
    ax = Figure().add_subplot()
    _ranked(ax, fit, 5.0)
    ax.figure.canvas.draw() if hasattr(ax.figure.canvas, "draw") else None
    ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert len(ticks) >= 3 and all(labels), labels


def test_report_figure_and_page_do_not_import_each_other():
    for name in ("figure", "page"):
        text = (Path(__file__).resolve().parents[1] / "rwhec_ros" / "report" /
                f"{name}.py").read_text()
        other = "page" if name == "figure" else "figure"
        assert f"from .{other} import" not in text


# --- helpers ------------------------------------------------------------------------------------


def _synthetic(tmp_path: Path) -> Path:
    from rwhec_ros.core.synthetic import random_instance

    path = tmp_path / "in.yaml"
    if not path.exists():
        problem, _ = random_instance(np.random.default_rng(7), 2, 2, n_per_edge=8,
                                     sigma=0.005, kappa=400.0)
        Dataset.from_problem(problem).save(path)
    return path


def _big(tmp_path: Path) -> Path:
    from rwhec_ros.core.synthetic import random_instance

    path = tmp_path / "big_in.yaml"
    problem, _ = random_instance(np.random.default_rng(2), 2, 2, n_per_edge=600)
    Dataset.from_problem(problem).save(path)
    return path
