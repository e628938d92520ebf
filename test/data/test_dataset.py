"""Our data set format: lossless round trips, conversions, and bad files."""

import hashlib
import io
from pathlib import Path

import numpy as np
import pytest
import yaml

from rwhec_ros import __version__
from rwhec_ros.core.lie import make_transform, so3_exp
from rwhec_ros.data.dataset import Dataset, DatasetEdge
from rwhec_ros.simulation.synthetic import random_instance, random_transforms
from rwhec_ros.sync.accumulator import PairAccumulator

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"
FIELDS = ("stamps_ns", "A", "B", "sigma", "kappa")


def awkward_dataset(rng):
    """Values that stress float repr: tiny, huge, negative zero, 17-digit mantissas."""
    problem, _ = random_instance(rng, 2, 2, edges=[(0, 0), (1, 0), (1, 1)], n_per_edge=4,
                                 sigma=0.01, kappa=200.0)
    stamps = [1_700_000_000_123_456_789 + np.arange(e.n, dtype=np.int64) * 33_333_333
              for e in problem.edges]
    ds = Dataset.from_problem(problem, stamps=stamps, metadata={"config": {"tag_size_m": 0.16}},
                              carriers={"y0": "base_link", "x0": "world"})
    e = ds.edges[0]
    A = e.A.copy()
    A[0, :3, 3] = [-0.0, 1e-300, 1.2345678901234567e-5]
    A[1] = make_transform(so3_exp([1e-17, 0.0, 0.0]), [1e300, -5e-324, 0.1 + 0.2])
    sigma = e.sigma.copy()
    sigma[:] = [5e-324, 0.1, 1.0 / 3.0, 1e-3]
    kappa = e.kappa.copy()
    kappa[0] = 1.7976931348623157e308
    edges = (DatasetEdge(e.x, e.y, e.stamps_ns, A, e.B, sigma, kappa),) + ds.edges[1:]
    return Dataset(ds.x_names, ds.y_names, edges, unknown_scale=True, metadata=ds.metadata,
                   carriers=ds.carriers)


def assert_bit_exact(ds1, ds2):
    assert ds2.x_names == ds1.x_names and ds2.y_names == ds1.y_names
    assert ds2.unknown_scale == ds1.unknown_scale
    assert ds2.metadata == ds1.metadata and ds2.carriers == ds1.carriers
    assert [(e.x, e.y) for e in ds2.edges] == [(e.x, e.y) for e in ds1.edges]
    for e1, e2 in zip(ds1.edges, ds2.edges):
        for f in FIELDS:
            a, b = getattr(e1, f), getattr(e2, f)
            assert a.dtype == b.dtype and a.shape == b.shape
            # Bit-exact, including the sign of zero and subnormals.
            assert a.tobytes() == b.tobytes(), f"edge ({e1.x}, {e1.y}) {f}"


@pytest.mark.parametrize("arrays", ["inline", "npz"])
def test_round_trip_is_bit_exact(tmp_path, arrays):
    ds = awkward_dataset(np.random.default_rng(0))
    path = ds.save(tmp_path / "collected.yaml", arrays=arrays)
    assert path == tmp_path / "collected.yaml"
    assert (tmp_path / "collected.npz").exists() == (arrays == "npz")
    header = yaml.safe_load(path.read_text())
    assert header["format"] == "rwhec_ros.dataset" and header["version"] == 1
    assert header["metadata"]["package_version"] == __version__
    assert header["metadata"]["config"] == {"tag_size_m": 0.16}
    assert_bit_exact(ds, Dataset.load(path))


def test_auto_switches_to_npz_above_threshold(tmp_path):
    ds = awkward_dataset(np.random.default_rng(1))  # 12 pairs
    ds.save(tmp_path / "small.yaml", inline_max_pairs=12)
    ds.save(tmp_path / "large.yaml", inline_max_pairs=11)
    assert not (tmp_path / "small.npz").exists()
    assert "A" in yaml.safe_load((tmp_path / "small.yaml").read_text())["edges"][0]
    assert (tmp_path / "large.npz").exists()
    assert_bit_exact(Dataset.load(tmp_path / "small.yaml"), Dataset.load(tmp_path / "large.yaml"))


def test_problem_round_trip_and_min_pairs():
    rng = np.random.default_rng(2)
    problem, _ = random_instance(rng, 3, 2, edges=[(0, 0), (1, 0), (2, 1)], n_per_edge=3)
    ds = Dataset.from_problem(problem)
    np.testing.assert_array_equal(ds.edges[0].stamps_ns, [0, 1, 2])  # placeholder stamps
    p2 = ds.to_problem()
    assert p2.x_names == problem.x_names and p2.y_names == problem.y_names
    for e1, e2 in zip(problem.edges, p2.edges):
        for f in ("A", "B", "sigma", "kappa"):
            np.testing.assert_array_equal(getattr(e1, f), getattr(e2, f))
    # Drop one pair of edge (2, 1): min_pairs=3 removes it and frames x2, y1.
    e = ds.edges[2]
    short = DatasetEdge(e.x, e.y, e.stamps_ns[:2], e.A[:2], e.B[:2], e.sigma[:2], e.kappa[:2])
    ds_short = Dataset(ds.x_names, ds.y_names, ds.edges[:2] + (short,))
    p3 = ds_short.to_problem(min_pairs=3)
    assert p3.x_names == ("x0", "x1") and p3.y_names == ("y0",)
    with pytest.raises(ValueError, match="min_pairs=4"):
        ds.to_problem(min_pairs=4)
    with pytest.raises(ValueError, match="stamps"):
        Dataset.from_problem(problem, stamps=[np.arange(3)])


def test_from_accumulator(tmp_path):
    rng = np.random.default_rng(3)
    acc = PairAccumulator()
    A = random_transforms(rng, 8)
    B = random_transforms(rng, 8)
    for i in range(8):
        acc.offer("tag_1" if i % 2 else "tag_0", "cam_0", 1000 + i, A[i], B[i], 0.01, 125.0)
    ds = Dataset.from_accumulator(acc, metadata={"config": {"keyframe_rotation_deg": 2.0}},
                                  carriers={"cam_0": "base_link"})
    assert ds.x_names == ("tag_0", "tag_1") and ds.y_names == ("cam_0",)
    np.testing.assert_array_equal(ds.edge("tag_1", "cam_0").stamps_ns, [1001, 1003, 1005, 1007])
    np.testing.assert_array_equal(ds.edge("tag_0", "cam_0").A, A[0::2])
    assert ds.n_pairs == 8
    assert_bit_exact(ds, Dataset.load(ds.save(tmp_path / "acc.yaml")))
    with pytest.raises(ValueError, match="not listed"):
        Dataset.from_accumulator(acc, x_names=["tag_0"])


def test_paper_real_world_data_round_trip(tmp_path):
    directory = SHARED / "data" / "paper_real_world"
    if not directory.is_dir():
        pytest.skip(f"shared data not available at {directory}")
    paper_csv = pytest.importorskip("rwhec_ros.data.paper_csv")
    problem = paper_csv.read_paper_csv(directory, min_pairs=1)
    ds = Dataset.from_problem(problem, metadata={"source": "paper_real_world"})
    loaded = Dataset.load(ds.save(tmp_path / "paper.yaml", arrays="npz"))
    assert_bit_exact(ds, loaded)
    assert loaded.to_problem().n_measurements == problem.n_measurements > 0


# --- bad files ---------------------------------------------------------------------------------
def small_doc(tmp_path):
    ds = awkward_dataset(np.random.default_rng(4))
    path = ds.save(tmp_path / "ds.yaml", arrays="inline")
    return path, yaml.safe_load(path.read_text())


def write(path, doc):
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _set(doc, keys, value):
    target = doc
    for k in keys[:-1]:
        target = target[k]
    target[keys[-1]] = value


def _delete(doc, keys):
    target = doc
    for k in keys[:-1]:
        target = target[k]
    del target[keys[-1]]


BAD_EDITS = [
    # (edit, expected message fragments after the file name)
    (lambda d: _set(d, ["format"], "rosbag2"), ["'format'", "'rosbag2'"]),
    (lambda d: _set(d, ["version"], 2), ["'version'", "got 2"]),
    (lambda d: _delete(d, ["x_names"]), ["'x_names'", "None"]),
    (lambda d: _delete(d, ["edges", 1, "B"]), ["edges[1] (x1, y0)", "'B'"]),
    (lambda d: _set(d, ["edges", 0, "x"], "x9"), ["edges[0] (x9, y0)", "'x9' is not in x_names"]),
    (lambda d: _set(d, ["edges", 2, "A", 1, 0, 0], 1.5),
     ["edges[2] (x1, y1)", "A[1]", "not orthonormal"]),
    (lambda d: _set(d, ["edges", 0, "A", 3, 1, 2], "abc"), ["edges[0] (x0, y0)", "'A'", "'abc'"]),
    (lambda d: _set(d, ["edges", 1, "stamps_ns", 2], 3.5), ["edges[1]", "'stamps_ns'", "3.5"]),
    (lambda d: _set(d, ["edges", 1, "n"], 7), ["edges[1]", "'n' is 7"]),
    (lambda d: _set(d, ["edges", 2, "sigma", 3], -0.01), ["edges[2]", "sigma[3]", "-0.01"]),
    (lambda d: _set(d, ["edges", 2, "kappa"], [1.0]), ["edges[2]", "kappa", "(4,)", "(1,)"]),
    (lambda d: _set(d, ["carriers"], {"cam_9": "base"}), ["carriers", "'cam_9'"]),
    (lambda d: _set(d, ["y_names"], ["y0", "y1", "x0"]), ["duplicated", "x0"]),
]


@pytest.mark.parametrize("edit, fragments", BAD_EDITS)
def test_bad_files_name_file_key_and_value(tmp_path, edit, fragments):
    path, doc = small_doc(tmp_path)
    edit(doc)
    write(path, doc)
    with pytest.raises(ValueError) as info:
        Dataset.load(path)
    message = str(info.value)
    assert message.startswith(str(path))
    for fragment in fragments:
        assert fragment in message, message


def test_bad_yaml_and_non_mapping(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("format: [unclosed\n")
    with pytest.raises(ValueError, match=r"broken\.yaml:\d+: not valid YAML"):
        Dataset.load(path)
    path.write_text("- just\n- a list\n")
    with pytest.raises(ValueError, match=r"broken\.yaml: expected a YAML mapping"):
        Dataset.load(path)


def test_bad_npz_sidecar(tmp_path):
    ds = awkward_dataset(np.random.default_rng(5))
    path = ds.save(tmp_path / "big.yaml", arrays="npz")
    npz = tmp_path / "big.npz"
    payload = npz.read_bytes()
    npz.write_bytes(payload[:-10] + b"0123456789")
    with pytest.raises(ValueError, match=r"big\.yaml: key 'arrays.sha256': big\.npz has SHA-256"):
        Dataset.load(path)
    npz.unlink()
    with pytest.raises(ValueError, match=r"big\.yaml: key 'arrays.file': cannot read"):
        Dataset.load(path)
    # A valid .npz (matching hash) that lacks an edge's array.
    arrays = {k: v for k, v in np.load(io.BytesIO(payload)).items() if k != "e1_B"}
    np.savez(npz, **arrays)
    doc = yaml.safe_load(path.read_text())
    doc["arrays"]["sha256"] = hashlib.sha256(npz.read_bytes()).hexdigest()
    write(path, doc)
    with pytest.raises(ValueError, match=r"big\.yaml: edges\[1\] \(x1, y0\): array 'e1_B' missing"):
        Dataset.load(path)


def test_construction_validation():
    e = DatasetEdge("t", "c", np.array([0, 1]), np.stack([np.eye(4)] * 2),
                    np.stack([np.eye(4)] * 2), np.full(2, 0.01), np.full(2, 100.0))
    with pytest.raises(ValueError, match="stamps_ns: expected integers"):
        DatasetEdge("t", "c", np.array([0.0, 1.0]), e.A, e.B, e.sigma, e.kappa)
    with pytest.raises(ValueError, match=r"stamps_ns\[1\]: must be >= 0"):
        DatasetEdge("t", "c", np.array([0, -1]), e.A, e.B, e.sigma, e.kappa)
    with pytest.raises(ValueError, match="B: expected 2 transforms"):
        DatasetEdge("t", "c", e.stamps_ns, e.A, e.B[:1], e.sigma, e.kappa)
    with pytest.raises(ValueError, match=r"metadata\.when: cannot store a object"):
        Dataset(("t",), ("c",), (e,), metadata={"when": object()})
    with pytest.raises(ValueError, match="duplicate edge"):
        Dataset(("t",), ("c",), (e, e))
    with pytest.raises(ValueError, match="unknown_scale"):
        Dataset(("t",), ("c",), (e,), unknown_scale="yes")
    ds = Dataset(("t", "unused"), ("c",), (e,), metadata={"n": np.int64(3), "v": np.ones(2)})
    assert ds.metadata == {"n": 3, "v": [1.0, 1.0]}
    assert ds.to_problem().x_names == ("t",)  # frames without an edge are dropped


# --- corners, intrinsics, tag sizes (reprojection error per camera, issue 11) -------------------

OLD_FORMAT = """\
format: rwhec_ros.dataset
version: 1
unknown_scale: false
x_names: [tag_0]
y_names: [cam_0]
carriers: {cam_0: rig, tag_0: world}
metadata: {created: '2026-11-20T10:00:00+00:00', package_version: 0.1.0, config: {}}
edges:
- x: tag_0
  y: cam_0
  n: 1
  stamps_ns: [1000]
  sigma: [0.01]
  kappa: [125.0]
  A:
  - - [1.0, 0.0, 0.0, 0.5]
    - [0.0, 1.0, 0.0, 0.0]
    - [0.0, 0.0, 1.0, 0.0]
    - [0.0, 0.0, 0.0, 1.0]
  B:
  - - [1.0, 0.0, 0.0, 0.0]
    - [0.0, 1.0, 0.0, 0.0]
    - [0.0, 0.0, 1.0, 2.0]
    - [0.0, 0.0, 0.0, 1.0]
"""


def test_a_file_written_before_corners_were_kept_still_loads(tmp_path):
    from rwhec_ros.data.corners import corner_data

    path = tmp_path / "old.yaml"
    path.write_text(OLD_FORMAT)  # the format as written before corners/intrinsics existed
    ds = Dataset.load(path)
    assert ds.n_pairs == 1 and ds.edges[0].corners_px is None
    assert ds.intrinsics == {} and ds.tag_sizes_m == {}
    assert corner_data(ds) is None  # no reprojection error, nothing else changes
    np.testing.assert_array_equal(ds.edges[0].B[0, :3, 3], [0.0, 0.0, 2.0])
    # written again: still without the new keys
    again = yaml.safe_load(ds.save(tmp_path / "again.yaml").read_text())
    assert "intrinsics" not in again and "corners_px" not in again["edges"][0]


def _with_corners(rng):
    from rwhec_ros.vision.intrinsics import CameraIntrinsics

    ds = awkward_dataset(rng)
    corners = []
    for e in ds.edges:
        c = rng.uniform(0, 640, size=(e.n, 4, 2))
        c[0] = np.nan  # the first pair of every edge without corners
        corners.append(c)
    edges = tuple(DatasetEdge(e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa, corners_px=c)
                  for e, c in zip(ds.edges, corners, strict=True))
    K = np.array([[500.0, 0.0, 320.0], [0.0, 501.0, 240.5], [0.0, 0.0, 1.0]])
    intr = {"y0": CameraIntrinsics(640, 480, K, np.array([0.1, -0.2, 1e-3, 2e-3, 0.05]))}
    return Dataset(ds.x_names, ds.y_names, edges, unknown_scale=True, metadata=ds.metadata,
                   carriers=ds.carriers, intrinsics=intr, tag_sizes_m={"x0": 0.16, "x1": 0.08})


def _round_trip(ds, path, arrays):
    """``ds`` saved and loaded again: pairs bit-exact, corners and board points equal."""
    back = Dataset.load(ds.save(path, arrays=arrays))
    assert_bit_exact(ds, back)
    for e1, e2 in zip(ds.edges, back.edges, strict=True):
        # NaN rows stay NaN (the sign bit of a NaN is not kept by YAML), the others exact
        for key in ("corners_px", "corner_points_m"):
            a, b = getattr(e1, key), getattr(e2, key)
            assert (a is None) == (b is None), key
            if a is not None:
                np.testing.assert_array_equal(a, b)
    return back


@pytest.mark.parametrize("arrays", ["inline", "npz"])
def test_corners_intrinsics_and_tag_sizes_round_trip(tmp_path, arrays):
    from rwhec_ros.data.corners import corner_observations

    ds = _with_corners(np.random.default_rng(4))
    back = _round_trip(ds, tmp_path / "c.yaml", arrays)
    assert back.intrinsics == ds.intrinsics and back.tag_sizes_m == {"x0": 0.16, "x1": 0.08}
    obs = corner_observations(back)
    # the pairs with corners, of cameras with intrinsics (y0 only) and tags with a size
    assert len(obs) == sum(e.n - 1 for e in ds.edges if e.y == "y0")
    assert {o.y for o in obs} == {"y0"}


def test_bad_corner_data_is_named():
    ds = _with_corners(np.random.default_rng(5))
    e = ds.edges[0]
    bad = e.corners_px.copy()
    bad[1, 2, 0] = np.nan  # three corners only
    with pytest.raises(ValueError, match=r"corners_px\[1\]: expected 4 finite corners"):
        DatasetEdge(e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa, corners_px=bad)
    with pytest.raises(ValueError, match=r"corners_px: expected shape \(4, 4, 2\)"):
        DatasetEdge(e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa, corners_px=bad[:, :3])
    with pytest.raises(ValueError, match="intrinsics: 'cam9' is not a camera"):
        Dataset(ds.x_names, ds.y_names, ds.edges, intrinsics={"cam9": ds.intrinsics["y0"]})
    with pytest.raises(ValueError, match=r"intrinsics\['y0'\]: missing key 'K'"):
        Dataset(ds.x_names, ds.y_names, ds.edges, intrinsics={"y0": {"width": 1, "height": 1}})
    with pytest.raises(ValueError, match=r"tag_sizes_m\['x0'\]: must be finite and > 0"):
        Dataset(ds.x_names, ds.y_names, ds.edges, tag_sizes_m={"x0": -1.0})


def test_accumulator_keeps_the_corners_of_kept_pairs(tmp_path):
    rng = np.random.default_rng(6)
    acc = PairAccumulator(max_pairs_per_edge=3)
    A = random_transforms(rng, 6)
    B = random_transforms(rng, 6)
    corners = rng.uniform(0, 100, size=(6, 4, 2))
    for i in range(6):
        c = None if i == 1 else corners[i]
        acc.offer("tag_0", "cam_0", 1000 + i, A[i], B[i], 0.01, 125.0, corners_px=c)
    e = acc.edges()[("tag_0", "cam_0")]
    assert e.n == 3 and e.corners_px.shape == (3, 4, 2)
    for stamp, c in zip(e.stamps_ns, e.corners_px, strict=True):
        i = int(stamp) - 1000  # a replaced pair's corners go with it
        if i == 1:
            assert np.isnan(c).all()
        else:
            np.testing.assert_array_equal(c, corners[i])
    # corners that are not four finite points: the pair is kept, without corners
    acc2 = PairAccumulator()
    acc2.offer("tag_0", "cam_0", 5, A[0], B[0], 0.01, 125.0, corners_px=[[1.0, 2.0]])
    assert acc2.edges()[("tag_0", "cam_0")].corners_px is None


def _with_board_corners(rng):
    """:func:`_with_corners` whose edge (x1, y0) is a board's: per pair a different number of
    corners (4..12, the rest NaN: a partly seen board) with their board-frame points; the
    first pair without corners."""
    ds = _with_corners(rng)
    edges = []
    for e in ds.edges:
        if (e.x, e.y) != ("x1", "y0"):
            edges.append(e)
            continue
        c = np.full((e.n, 12, 2), np.nan)
        p = np.full((e.n, 12, 3), np.nan)
        for i in range(1, e.n):
            k = 4 + 2 * i
            c[i, :k] = rng.uniform(0, 640, size=(k, 2))
            p[i, :k, :2] = rng.uniform(-0.3, 0.3, size=(k, 2))
            p[i, :k, 2] = 0.0
        edges.append(DatasetEdge(e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa,
                                 corners_px=c, corner_points_m=p))
    return Dataset(ds.x_names, ds.y_names, tuple(edges), unknown_scale=True,
                   metadata=ds.metadata, carriers=ds.carriers, intrinsics=ds.intrinsics,
                   tag_sizes_m={"x0": 0.16})  # the board has no tag size


@pytest.mark.parametrize("arrays", ["inline", "npz"])
def test_board_corners_round_trip(tmp_path, arrays):
    from rwhec_ros.data.corners import corner_observations

    ds = _with_board_corners(np.random.default_rng(7))
    back = _round_trip(ds, tmp_path / "b.yaml", arrays)
    board = back.edge("x1", "y0")
    assert board.corners_px.shape == (board.n, 12, 2)
    obs = [o for o in corner_observations(back) if o.x == "x1"]
    # one observation per pair with corners, with only the corners seen, and their points
    assert [len(o.corners_px) for o in obs] == [4 + 2 * i for i in range(1, board.n)]
    for i, o in enumerate(obs, start=1):
        np.testing.assert_array_equal(o.object_points, board.corner_points_m[i, :4 + 2 * i])
        assert o.tag_size_m is None
    # the tag edge of the same camera keeps its four corners and its size
    assert {len(o.corners_px) for o in corner_observations(back) if o.x == "x0"} == {4}


def test_a_file_with_tag_corners_and_cornerless_boards_still_loads(tmp_path):
    """A data set as written before boards kept corners: tag edges with four corners per pair,
    board edges with none (no ``corner_points_m`` anywhere)."""
    from rwhec_ros.data.corners import corner_observations

    ds = _with_corners(np.random.default_rng(8))
    path = ds.save(tmp_path / "old.yaml", arrays="inline")
    doc = yaml.safe_load(path.read_text())
    for ed in doc["edges"]:
        if ed["x"] == "x1":
            del ed["corners_px"]  # a board edge of then: no corners
        assert "corner_points_m" not in ed
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    back = Dataset.load(path)
    assert back.edge("x1", "y0").corners_px is None
    assert back.edge("x1", "y0").corner_points_m is None
    np.testing.assert_array_equal(back.edge("x0", "y0").corners_px, ds.edge("x0", "y0").corners_px)
    assert {o.x for o in corner_observations(back)} == {"x0"}


def test_bad_board_corner_data_is_named():
    ds = _with_board_corners(np.random.default_rng(9))
    e = ds.edge("x1", "y0")
    args = (e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa)
    p = e.corner_points_m.copy()
    p[1, 0] = np.nan  # a corner without its point
    with pytest.raises(ValueError, match=r"corners_px\[1\]\[0\] / corner_points_m\[1\]\[0\]: "
                                         r"a point must be finite in both"):
        DatasetEdge(*args, corners_px=e.corners_px, corner_points_m=p)
    c, p = e.corners_px.copy(), e.corner_points_m.copy()
    c[1, 3:], p[1, 3:] = np.nan, np.nan  # three points
    with pytest.raises(ValueError, match=r"corners_px\[1\]: expected at least 4 points or none"):
        DatasetEdge(*args, corners_px=c, corner_points_m=p)
    with pytest.raises(ValueError, match=r"corner_points_m: expected shape \(4, 12, 3\)"):
        DatasetEdge(*args, corners_px=e.corners_px, corner_points_m=e.corner_points_m[:, :11])
    with pytest.raises(ValueError, match="corner_points_m: given without corners_px"):
        DatasetEdge(*args, corner_points_m=e.corner_points_m)


def test_accumulator_keeps_board_corners_and_bounds_their_memory():
    rng = np.random.default_rng(10)
    acc = PairAccumulator(max_pairs_per_edge=3, max_edges=2, board_corners=36)
    A, B = random_transforms(rng, 5), random_transforms(rng, 5)
    sizes = [8, 36, 12, 20, 16]
    pts = [rng.uniform(-0.1, 0.1, size=(k, 3)) for k in sizes]
    px = [rng.uniform(0, 640, size=(k, 2)) for k in sizes]
    for i in range(5):
        acc.offer("board_0", "cam_0", 100 + i, A[i], B[i], 0.01, 125.0, corners_px=px[i],
                  corner_points_m=pts[i])
        acc.offer("tag_0", "cam_0", 100 + i, A[i], B[i], 0.01, 125.0, corners_px=px[i][:4])
    e = acc.edges()[("board_0", "cam_0")]
    assert e.n == 3 and e.corner_points_m is not None
    assert e.corners_px.shape[1] == max(sizes[int(s) - 100] for s in e.stamps_ns)
    for s, c, p in zip(e.stamps_ns, e.corners_px, e.corner_points_m, strict=True):
        k = sizes[int(s) - 100]  # a replaced pair's corners go with it, the rest NaN
        np.testing.assert_array_equal(c[:k], px[int(s) - 100])
        np.testing.assert_array_equal(p[:k], pts[int(s) - 100])
        assert np.isnan(c[k:]).all() and np.isnan(p[k:]).all()
    tag = acc.edges()[("tag_0", "cam_0")]
    assert tag.corners_px.shape == (3, 4, 2) and tag.corner_points_m is None
    # the bound covers the widened board slots: 360 + 16 (M - 4) + 24 M bytes per slot
    assert acc.nbytes() <= acc.memory_bound_bytes() == 2 * ((360 + 16 * 32 + 24 * 36) * 3 + 8192)
    # more corners than board_corners, or board corners without board_corners: pair kept,
    # corners not
    small = PairAccumulator(board_corners=0)
    assert small.offer("board_0", "cam_0", 1, A[0], B[0], 0.01, 125.0, corners_px=px[0],
                       corner_points_m=pts[0])
    assert small.edges()[("board_0", "cam_0")].corners_px is None
    with pytest.raises(ValueError, match="board_corners: expected 0 or an integer >= 4"):
        PairAccumulator(board_corners=3)


# --- time offsets: the recorded pose stream and the offsets in the pairs ------------------------


def _with_stream(rng):
    from rwhec_ros.sync.pose_track import PoseTrackData

    ds = awkward_dataset(rng)
    stamps = 1_700_000_000_000_000_000 + np.arange(7, dtype=np.int64) * 10_000_000
    poses = random_transforms(rng, 7)
    stream = PoseTrackData(stamps, poses, 100_000_000)
    return Dataset(ds.x_names, ds.y_names, ds.edges, unknown_scale=True, metadata=ds.metadata,
                   carriers=ds.carriers, time_offsets_s={"y0": -0.025}, pose_stream=stream)


@pytest.mark.parametrize("arrays", ["inline", "npz"])
def test_pose_stream_and_time_offsets_round_trip(tmp_path, arrays):
    ds = _with_stream(np.random.default_rng(6))
    back = _round_trip(ds, tmp_path / "t.yaml", arrays)
    assert back.time_offsets_s == {"y0": -0.025}
    assert back.pose_stream.max_gap_ns == 100_000_000
    assert back.pose_stream.stamps_ns.tobytes() == ds.pose_stream.stamps_ns.tobytes()
    assert back.pose_stream.poses.tobytes() == ds.pose_stream.poses.tobytes()
    # a data set without them (written before they were kept) has neither
    plain = _round_trip(awkward_dataset(np.random.default_rng(6)), tmp_path / "p.yaml", arrays)
    assert plain.pose_stream is None and plain.time_offsets_s == {}


def test_bad_time_data_is_named(tmp_path):
    ds = _with_stream(np.random.default_rng(7))
    with pytest.raises(ValueError, match=r"time_offsets_s: 'x0' is not a camera"):
        Dataset(ds.x_names, ds.y_names, ds.edges, time_offsets_s={"x0": 0.1})
    with pytest.raises(ValueError, match=r"time_offsets_s\['y0'\]: expected finite seconds"):
        Dataset(ds.x_names, ds.y_names, ds.edges, time_offsets_s={"y0": float("nan")})
    path = ds.save(tmp_path / "t.yaml", arrays="inline")
    doc = yaml.safe_load(path.read_text())
    doc["pose_stream"]["stamps_ns"][3] = doc["pose_stream"]["stamps_ns"][2]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match=r"t.yaml: pose_stream: pose_stream stamps_ns\[3\]"):
        Dataset.load(path)
