"""``rwhec-calibrate check`` on data sets (the bag and samples inputs go through the same session
as ``bag`` and ``samples``; the rendered path is exercised by the benchmark's docs recipe)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_bringup import _data, _moved, _truth

from rwhec_ros.cli import main
from rwhec_ros.cli.check import input_kind
from rwhec_ros.cli.common import EXIT_BAD_INPUT, EXIT_MOVED, EXIT_OK, EXIT_UNDECIDED
from rwhec_ros.data.dataset import Dataset


def _run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main(list(argv), stdout=out, stderr=err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """result.yaml of ``rwhec-calibrate dataset`` on 80 pairs per edge of the test rig."""
    X, Y = _truth(20)
    d = tmp_path_factory.mktemp("ref")
    Dataset.from_problem(_data(np.random.default_rng(21), X, Y, 80)).save(d / "data.yaml")
    code, out, err = _run("dataset", str(d / "data.yaml"), "-o", str(d / "out"), "--folds", "0",
                          "--no-guidance", "-q")
    assert code == EXIT_OK, out + err
    return d / "out" / "result.yaml"


def _dataset(path: Path, seed: int, n: int, moved_mm: float = 0.0) -> Path:
    X, Y = _truth(20)
    if moved_mm:
        Y = _moved(Y, 1, moved_mm, 0.0)
    Dataset.from_problem(_data(np.random.default_rng(seed), X, Y, n)).save(path)
    return path


def test_consistent_exits_0_and_writes_the_check(reference, tmp_path):
    data = _dataset(tmp_path / "new.yaml", 22, 30)
    code, out, err = _run("check", "--reference", str(reference), str(data), "-o",
                          str(tmp_path / "chk"), "-q")
    assert code == EXIT_OK, out + err
    lines = out.splitlines()
    assert lines[0].startswith("CHECK CONSISTENT")
    assert lines[1].startswith(("GOOD", "CAUTION"))
    for name in ("check.yaml", "static_transforms.launch.py", "calibration.urdf.xacro",
                 "frames.yaml", "dataset.yaml"):
        assert (tmp_path / "chk" / name).exists()
        assert f"{tmp_path / 'chk' / name}" in out
    doc = yaml.safe_load((tmp_path / "chk" / "check.yaml").read_text())
    assert doc["check"]["status"] == "consistent" and doc["check"]["updated"] == []
    # existing files are refused without --force (exit 2), overwritten with it
    code, out, err = _run("check", "--reference", str(reference), str(data), "-o",
                          str(tmp_path / "chk"), "-q")
    assert code == EXIT_BAD_INPUT and "refusing to overwrite" in err
    code, out, err = _run("check", "--reference", str(reference), str(data), "-o",
                          str(tmp_path / "chk"), "-q", "--force")
    assert code == EXIT_OK


def test_a_moved_camera_exits_5(reference, tmp_path):
    data = _dataset(tmp_path / "new.yaml", 23, 30, moved_mm=8.0)
    code, out, err = _run("check", "--reference", str(reference), str(data), "-o",
                          str(tmp_path / "chk"), "-q")
    assert code == EXIT_MOVED, out + err
    assert out.startswith("CHECK MOVED: cam1: MOVED by ")
    doc = yaml.safe_load((tmp_path / "chk" / "check.yaml").read_text())
    assert doc["check"]["updated"] == ["cam1"]
    frames = yaml.safe_load((tmp_path / "chk" / "frames.yaml").read_text())["frames"]
    ref = {f["name"]: f for f in yaml.safe_load(reference.read_text())["frames"]}
    by_child = {f["child"]: f for f in frames}
    # cam0 as in the reference, cam1 re-estimated (8 mm away from it)
    np.testing.assert_allclose(by_child["cam0_calibrated"]["xyz"], ref["cam0"]["translation"],
                               atol=1e-12)
    moved = np.linalg.norm(np.subtract(by_child["cam1_calibrated"]["xyz"],
                                       ref["cam1"]["translation"]))
    assert 0.006 < moved < 0.010


def test_too_few_pairs_exit_6_and_a_tighter_tolerance_needs_more(reference, tmp_path):
    data = _dataset(tmp_path / "few.yaml", 24, 4)
    code, out, _ = _run("check", "--reference", str(reference), str(data), "-o",
                        str(tmp_path / "a"), "-q")
    assert code == EXIT_UNDECIDED, out
    assert out.startswith("CHECK NOT ENOUGH DATA YET")
    data = _dataset(tmp_path / "new.yaml", 25, 30)
    code, out, _ = _run("check", "--reference", str(reference), str(data), "-o",
                        str(tmp_path / "b"), "-q", "--tolerance-mm", "0.01",
                        "--tolerance-deg", "0.001")
    assert code == EXIT_UNDECIDED, out


def test_bad_input_exits_2(reference, tmp_path):
    data = _dataset(tmp_path / "new.yaml", 26, 5)
    code, _, err = _run("check", "--reference", str(tmp_path / "missing.yaml"), str(data))
    assert code == EXIT_BAD_INPUT and "--reference" in err
    code, _, err = _run("check", "--reference", str(reference), str(tmp_path / "nothing"))
    assert code == EXIT_BAD_INPUT and "no such file" in err
    code, _, err = _run("check", "--reference", str(reference), str(data),
                        "--false-alarm-rate", "2")
    assert code == EXIT_BAD_INPUT and "false-alarm rate" in err
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    code, _, err = _run("check", "--reference", str(reference), str(tmp_path / "bag"))
    assert code == EXIT_BAD_INPUT and "needs --config" in err


def test_input_kinds(tmp_path):
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("x: 1\n")
    assert input_kind(tmp_path / "bag") == "bag"
    assert input_kind(_dataset(tmp_path / "d.yaml", 1, 3)) == "dataset"
    (tmp_path / "views").mkdir()
    assert input_kind(tmp_path / "views") == "samples"
    (tmp_path / "run").mkdir()
    _dataset(tmp_path / "run" / "dataset.yaml", 1, 3)
    assert input_kind(tmp_path / "run") == "dataset"


# --- the run: phases, the kept data set, --force, interrupts, failed writes --------------------


def test_a_check_goes_through_the_run_phases_and_keeps_the_pairs_first(reference, tmp_path,
                                                                       monkeypatch):
    from rwhec_ros.cli.run import Run

    seen: list[tuple[str, list[str]]] = []
    real = Run.enter

    def enter(self, phase, *, pause=True):
        d = self.paths.result.parent if self.paths is not None else None
        seen.append((phase, sorted(p.name for p in d.iterdir()) if d and d.exists() else []))
        real(self, phase, pause=pause)

    monkeypatch.setattr(Run, "enter", enter)
    data = _dataset(tmp_path / "new.yaml", 27, 30)
    code, out, err = _run("check", "--reference", str(reference), str(data), "-o",
                          str(tmp_path / "chk"), "-q")
    assert code == EXIT_OK, out + err
    assert [p for p, _ in seen] == ["reading", "solving", "analysing", "writing"]
    # the data set is on disk before the solve, the answer only after the writing phase
    assert seen[1][1] == ["dataset.yaml"] and "check.yaml" not in seen[3][1]


@pytest.mark.parametrize("terminated", [False, True])
def test_an_interrupted_check_keeps_the_pairs_and_names_the_check_that_resumes_it(
        reference, tmp_path, monkeypatch, terminated):
    import shlex

    import rwhec_ros.session.bringup as bringup
    from rwhec_ros.cli.common import EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated

    real = bringup.run_check

    def interrupted(*args, on_phase=None, **kwargs):
        def phase(name):
            on_phase(name)
            raise Terminated() if terminated else KeyboardInterrupt()
        return real(*args, on_phase=phase, **kwargs)

    monkeypatch.setattr(bringup, "run_check", interrupted)
    data = _dataset(tmp_path / "new.yaml", 28, 30, moved_mm=8.0)
    out = tmp_path / "chk"
    code, stdout, err = _run("check", "--reference", str(reference), str(data), "-o", str(out),
                             "-q", "--tolerance-deg", "0.3")
    assert code == (EXIT_TERMINATED if terminated else EXIT_INTERRUPTED), err
    assert stdout == "" and len(err.splitlines()) == 1 and "Traceback" not in err
    sig = "SIGTERM" if terminated else "SIGINT"
    assert f"check: interrupted ({sig}) while analysing; the 180 pairs gathered are in " in err
    resume = err.split("resume with: ")[1].strip()
    assert resume == (f"rwhec-calibrate check {out / 'dataset.yaml'} -o {out} --force "
                      f"--reference {reference} --tolerance-deg 0.3")
    assert sorted(p.name for p in out.iterdir()) == ["dataset.yaml"]
    monkeypatch.setattr(bringup, "run_check", real)
    code, stdout, err = _run(*shlex.split(resume)[1:], "-q")
    assert code == EXIT_MOVED and stdout.startswith("CHECK MOVED: cam1: MOVED by "), err


def test_force_replaces_an_earlier_calibration_and_the_reference_is_never_an_output(
        reference, tmp_path):
    out = tmp_path / "chk"
    out.mkdir()
    for name in ("result.yaml", "report.png", "dataset.npz"):
        (out / name).write_text("an earlier run\n")
    data = _dataset(tmp_path / "new.yaml", 29, 30)
    # refused before any work, naming the earlier calibration's files
    code, stdout, err = _run("check", "--reference", str(reference), str(data), "-o", str(out),
                             "-q")
    assert code == EXIT_BAD_INPUT and "refusing to overwrite existing file(s)" in err
    assert "result.yaml" in err and stdout == ""
    code, stdout, err = _run("check", "--reference", str(reference), str(data), "-o", str(out),
                             "-q", "--force")
    assert code == EXIT_OK, err
    assert sorted(p.name for p in out.iterdir()) == [
        "calibration.urdf.xacro", "check.yaml", "dataset.yaml", "frames.yaml",
        "static_transforms.launch.py"]
    # a calibration into a check's directory: its check.yaml is refused too, --force removes it
    code, _, err = _run("dataset", str(data), "-o", str(out), "-q", "--folds", "0")
    assert code == EXIT_BAD_INPUT and "check.yaml" in err
    code, _, err = _run("dataset", str(data), "-o", str(out), "-q", "--folds", "0", "--force")
    assert code == EXIT_OK and not (out / "check.yaml").exists(), err
    # the reference among the files -o DIR would replace: refused, with --force too
    code, _, err = _run("check", "--reference", str(out / "result.yaml"), str(data), "-o",
                        str(out), "-q", "--force")
    assert code == EXIT_BAD_INPUT and "whose outputs the check replaces" in err
    assert (out / "result.yaml").is_file() and not (out / "check.yaml").exists()


def test_without_o_a_new_check_directory_and_a_failed_write_keeps_the_pairs(
        reference, tmp_path, monkeypatch):
    import errno
    import os

    import rwhec_ros.data.atomic as atomic

    monkeypatch.chdir(tmp_path)
    data = _dataset(tmp_path / "new.yaml", 30, 30)
    code, stdout, err = _run("check", "--reference", str(reference), str(data), "-q")
    assert code == EXIT_OK, err
    (made,) = (tmp_path / "rwhec_output").iterdir()
    assert made.name.startswith("check_") and (made / "check.yaml").is_file()
    real = atomic._write_temp

    def full(path, payload):
        if path.name != "dataset.yaml":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(path, payload)

    monkeypatch.setattr(atomic, "_write_temp", full)
    out = tmp_path / "full"
    code, stdout, err = _run("check", "--reference", str(reference), str(data), "-o", str(out),
                             "-q")
    assert code == EXIT_BAD_INPUT and stdout == "" and len(err.splitlines()) == 1, err
    assert f"cannot write the outputs into {out}: no space left on device" in err
    assert f"resume with: rwhec-calibrate check {out / 'dataset.yaml'}" in err
    assert sorted(p.name for p in out.iterdir()) == ["dataset.yaml"]
