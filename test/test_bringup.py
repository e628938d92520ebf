"""The bring-up check (rwhec_ros.session.bringup, its outputs and the references of
rwhec_ros.data.reference), ROS-free, on seeded synthetic rigs."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from rwhec_ros.core.lie import invert_transform, make_transform, rotation_distance, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.data.export import frames_yaml, urdf_snippet
from rwhec_ros.data.reference import (
    Reference,
    fixed_chain,
    read_reference,
    reference_from_result,
)
from rwhec_ros.data.results import FrameNaming, load_result
from rwhec_ros.session.bringup import BringupCheck, CheckOptions, run_check
from rwhec_ros.session.bringup_outputs import (
    check_document,
    check_message,
    check_rows,
    write_check_outputs,
)
from rwhec_ros.simulation.synthetic import perturb_measurements, random_transforms

SIGMA, KAPPA = 0.0005, 3e4  # the data's true noise: 0.5 mm, 0.23 deg per axis
NAMING = FrameNaming.from_carriers(["tag_0", "tag_1"], ["cam0", "cam1", "cam2"],
                                   camera_carrier="rig", tag_carrier="world")


def _truth(seed: int = 0):
    rng = np.random.default_rng(seed)
    X = random_transforms(rng, 2, 0.5)
    Y = random_transforms(rng, 3, 0.5)
    return X, Y


def _data(rng, X, Y, n: int, stated=(0.005, 400.0)) -> Problem:
    """Every camera sees both tags from ``n`` random poses; the noise stated 10x too large."""
    edges = []
    for j in range(len(X)):
        for k in range(len(Y)):
            A = random_transforms(rng, n, 0.5)
            B = perturb_measurements(rng, invert_transform(Y[k]) @ A @ X[j], SIGMA, KAPPA)
            edges.append(Edge.build(f"tag_{j}", f"cam{k}", A, B, sigma=stated[0],
                                    kappa=stated[1]))
    return Problem(["tag_0", "tag_1"], ["cam0", "cam1", "cam2"], edges)


def _reference(X, Y, rng, n: int = 80) -> Reference:
    data = _data(rng, X, Y, n)
    res = solve(data)
    return Reference({n_: res.transform(n_) for n_ in data.frame_names}, source="reference")


def _moved(Y, k: int, mm: float, deg: float):
    out = Y.copy()
    R = so3_exp(np.radians(deg) * np.array([0.0, 0.6, 0.8])) @ Y[k][:3, :3]
    out[k] = make_transform(R, Y[k][:3, 3] + 1e-3 * mm * np.array([0.8, 0.0, -0.6]))
    return out


def test_nothing_moved_and_enough_data_is_consistent():
    X, Y = _truth()
    rng = np.random.default_rng(1)
    ref = _reference(X, Y, rng)
    report = run_check(_data(rng, X, Y, 30), ref)
    assert report.status == "consistent", check_message(report)
    assert report.updated == [] and report.moved == []
    for name in ref.frames:  # the outputs are the reference itself
        np.testing.assert_array_equal(report.frames[name], ref.frames[name])
    assert report.verdict is not None and report.verdict.usable
    message = check_message(report)
    assert message.splitlines()[0].startswith("CHECK CONSISTENT: every camera within 2.0 mm")
    assert report.verdict.headline() == message.splitlines()[1]
    assert all(f"cam{k}: consistent: changed by" in message for k in range(3))


def test_a_moved_camera_is_named_sized_and_re_estimated_alone():
    X, Y = _truth(2)
    rng = np.random.default_rng(3)
    ref = _reference(X, Y, rng)
    Ym = _moved(Y, 1, 6.0, 0.5)
    data = _data(rng, X, Ym, 30)
    report = run_check(data, ref)
    assert report.status == "moved" and report.moved == ["cam1"]
    c = report.changes["cam1"]
    # the estimated size within 4 std of the true change (6 mm, 0.5 deg)
    assert abs(c.translation_m - 0.006) < 4 * c.translation_std_m
    assert abs(c.rotation_deg - 0.5) < 4 * c.rotation_std_deg
    assert report.updated == ["cam1"]
    for name in ref.frames:
        if name != "cam1":
            np.testing.assert_array_equal(report.frames[name], ref.frames[name])
    # the re-estimate against the truth: within 1 mm / 0.05 deg (its std is ~0.1 mm here) and
    # no worse than twice a full calibration of the same data (the held frames add the
    # reference's own error, ~0.1 mm)
    new = report.frames["cam1"]
    full = solve(data).transform("cam1")
    err = np.linalg.norm(new[:3, 3] - Ym[1][:3, 3])
    err_full = np.linalg.norm(full[:3, 3] - Ym[1][:3, 3])
    assert err < 1e-3 and err < 2 * err_full + 1e-4
    assert np.degrees(rotation_distance(new[:3, :3], Ym[1][:3, :3])) < 0.05
    # the consistent frames were held: the certificate is for that problem, and says so
    assert report.result.certified
    assert "pseudo-measurements holding" in report.certificate_for
    message = check_message(report)
    assert message.startswith("CHECK MOVED: cam1: MOVED by ")
    assert "-> re-estimated" in message


def test_too_little_data_is_not_enough_data_yet():
    X, Y = _truth(4)
    rng = np.random.default_rng(5)
    ref = _reference(X, Y, rng)
    few = _data(rng, X, Y, 3, stated=(0.005, 400.0))
    report = run_check(few, ref, CheckOptions(noise="stated"))
    assert report.status == "undecided"
    assert check_message(report).startswith("CHECK NOT ENOUGH DATA YET: cam0, cam1, cam2")
    rows = check_rows(report, "calibrator")
    assert [r["name"] for r in rows] == ["calibrator: check", "calibrator: check cam0",
                                         "calibrator: check cam1", "calibrator: check cam2"]
    assert [r["level"] for r in rows] == [1, 1, 1, 1]
    assert rows[1]["message"].startswith("not enough data yet")


def test_a_reference_camera_without_data_keeps_the_answer_open():
    X, Y = _truth(6)
    rng = np.random.default_rng(7)
    ref = _reference(X, Y, rng)
    data = _data(rng, X, Y, 30)
    two = data.with_edges([e for e in data.edges if e.y != "cam2"])
    report = run_check(two, ref, expected_cameras=["cam0", "cam1", "cam2"])
    assert report.unseen == ["cam2"] and report.status == "undecided"
    assert "cam2: not enough data yet: no pairs of it in these data" in check_message(report)


def test_held_targets_are_the_gauge():
    X, Y = _truth(8)
    rng = np.random.default_rng(9)
    ref = _reference(X, Y, rng)
    report = run_check(_data(rng, X, _moved(Y, 0, 8.0, 0.0), 20), ref,
                       CheckOptions(hold="targets"))
    assert report.moved == ["cam0"]
    assert set(report.changes) == {"cam0", "cam1", "cam2"}  # the held targets are not tested
    assert "holding" in report.certificate_for and "tag_0" in report.certificate_for
    assert "the targets hold the reference" in check_message(report)


def test_bringup_check_counts_looks_and_spends_the_rate():
    X, Y = _truth(10)
    rng = np.random.default_rng(11)
    ref = _reference(X, Y, rng)
    checker = BringupCheck(ref)
    data = _data(rng, X, Y, 10)
    first = checker.check(data)
    assert checker.looks == 1 and first.look == 1
    assert checker.check(data) is first and checker.looks == 1  # same data: no new look
    more = _data(rng, X, Y, 12)
    second = checker.check(more)
    assert checker.looks == 2
    assert second.level == pytest.approx(first.level / 4)  # 6 a / (pi^2 n^2)


def test_run_check_refuses_data_without_a_referenced_camera():
    X, Y = _truth()
    rng = np.random.default_rng(0)
    ref = Reference({"tag_0": X[0]}, source="tags only")
    with pytest.raises(ValueError, match="no camera of the data"):
        run_check(_data(rng, X, Y, 5), ref)
    with pytest.raises(ValueError, match="hold"):
        CheckOptions(hold="cameras")
    with pytest.raises(ValueError, match="false-alarm rate"):
        CheckOptions(false_alarm_rate=0.0)


def test_check_yaml_is_the_next_reference_and_the_files_carry_only_the_moved_frame(tmp_path):
    X, Y = _truth(12)
    rng = np.random.default_rng(13)
    ref = _reference(X, Y, rng)
    report = run_check(_data(rng, X, _moved(Y, 2, 7.0, 0.0), 30), ref)
    assert report.updated == ["cam2"]
    files = write_check_outputs(tmp_path, report, NAMING, source={"type": "test"})
    assert set(files) == {"check", "launch", "urdf", "frames"}
    doc = load_result(tmp_path / "check.yaml")  # has every key a result reader needs
    assert doc["check"]["status"] == "moved" and doc["check"]["updated"] == ["cam2"]
    frames = {f["name"]: f for f in doc["frames"]}
    assert frames["cam2"]["updated"] and not frames["cam0"]["updated"]
    assert frames["cam2"]["covariance"] is not None  # the re-estimate's own uncertainty
    again = reference_from_result(doc, "check.yaml")
    np.testing.assert_allclose(again.frames["cam2"], report.frames["cam2"], atol=1e-12)
    np.testing.assert_allclose(again.frames["cam0"], ref.frames["cam0"], atol=1e-12)
    # the frames.yaml and the URDF snippet hold the same frames
    names = {n: (p, [c, n]) for n, (p, c) in NAMING.frames.items()}
    for path in (tmp_path / "frames.yaml", tmp_path / "calibration.urdf.xacro"):
        back = read_reference(path, names)
        for n in ("cam0", "cam2", "tag_1"):
            np.testing.assert_allclose(back.frames[n], report.frames[n], atol=1e-9)
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        write_check_outputs(tmp_path, report, NAMING)
    text = (tmp_path / "static_transforms.launch.py").read_text()
    assert text.startswith("# CHECK MOVED: cam2: MOVED by")
    assert check_document(report, NAMING)["check"]["frames"]["cam2"]["decision"] == "moved"


def test_references_from_frames_yaml_and_urdf_chains(tmp_path):
    X, Y = _truth(14)
    items = [("rig", "cam0_calibrated", Y[0]), ("world", "tag_0_calibrated", X[0])]
    (tmp_path / "frames.yaml").write_text(frames_yaml(items))
    names = {"cam0": ("rig", ["cam0_calibrated", "cam0"]),
             "tag_0": ("world", ["tag_0_calibrated", "tag_0"]),
             "cam1": ("rig", ["cam1_calibrated", "cam1"])}
    ref = read_reference(tmp_path / "frames.yaml", names)
    np.testing.assert_allclose(ref.frames["cam0"], Y[0], atol=1e-12)
    assert "cam1" not in ref.frames and any(n.startswith("cam1:") for n in ref.notes)
    assert not ref.has_covariance
    # a robot description: rig -> mount -> cam1 (fixed joints): composed down the chain
    mount = make_transform(so3_exp(np.array([0.0, 0.0, 0.3])), [0.1, 0.0, 0.2])
    urdf = urdf_snippet([("rig", "mount", mount),
                         ("mount", "cam1", invert_transform(mount) @ Y[1])])
    (tmp_path / "robot.urdf").write_text(urdf)
    ref = read_reference(tmp_path / "robot.urdf", names)
    np.testing.assert_allclose(ref.frames["cam1"], Y[1], atol=1e-9)
    joints = [("a", "b", mount), ("b", "c", mount)]
    np.testing.assert_allclose(fixed_chain(joints, "a", "c"), mount @ mount)
    assert fixed_chain(joints, "c", "a") is None
    # a carrier that differs is left out with the reason
    (tmp_path / "other.yaml").write_text(frames_yaml([("base", "cam0_calibrated", Y[0])]))
    with pytest.raises(ValueError, match="none of the frames"):
        read_reference(tmp_path / "other.yaml", {"cam0": names["cam0"]})
    (tmp_path / "bad.yaml").write_text("just: text\n")
    with pytest.raises(ValueError, match="expected a result.yaml"):
        read_reference(tmp_path / "bad.yaml", names)


def test_reference_from_a_result_uses_the_fit_for_its_covariance():
    C = np.eye(6) * 1e-6
    doc = {"frames": [
        {"name": "cam0", "matrix": np.eye(4).tolist(), "covariance": C.tolist(),
         "a_posteriori": {"covariance": (0.01 * C).tolist()}},
        {"name": "cam1", "matrix": np.eye(4).tolist(), "usable": False, "why": ["imprecise"]}],
        "verdict_details": {"fit": {"noise_ratio_translation": 0.2,
                                    "noise_ratio_rotation": 0.1}}}
    ref = reference_from_result(doc, "r.yaml")
    np.testing.assert_allclose(ref.covariance["cam0"], 0.04 * C)  # the larger ratio, squared
    assert "cam1" not in ref.frames and "usable: false" in ref.notes[0]
    del doc["verdict_details"]
    np.testing.assert_allclose(reference_from_result(doc, "r").covariance["cam0"], 0.01 * C)
    with pytest.raises(ValueError, match="frame cam0 matrix"):
        reference_from_result({"frames": [{"name": "cam0", "matrix": [[1, 2]]}]}, "r")
    assert yaml.safe_dump(doc)  # plain data
