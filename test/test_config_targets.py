"""Named targets in the configuration (``targets.names``): boards and single tags, validation."""

from __future__ import annotations

import pytest
from test_config import minimal

from rwhec_ros.config import CalibratorConfig
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec


def with_targets(**targets) -> dict:
    """``minimal()`` (tags 0, 1, 2 of tag36h11) plus named targets given as flat key dicts."""
    p = minimal()
    p["targets.names"] = list(targets)
    for name, keys in targets.items():
        p.update({f"targets.{name}.{k}": v for k, v in keys.items()})
    return p


GRID = {"type": "aprilgrid", "rows": 3, "cols": 4, "tag_size": 0.06, "first_id": 100}
CHARUCO = {"type": "charuco", "squares_x": 5, "squares_y": 4, "square_size": 0.08,
           "marker_size": 0.06, "dictionary": "DICT_4X4_250"}


def test_existing_configurations_have_no_named_targets():
    c = CalibratorConfig.from_parameters(minimal())
    assert c.targets.specs == ()
    assert c.x_names == ("tag_0", "tag_1", "tag_2")
    assert [t.name for t in c.target_specs()] == list(c.x_names)
    assert all(t.kind == "tag" and t.tag_size == 0.16 for t in c.target_specs())


def test_boards_and_tags_mixed_with_defaults():
    c = CalibratorConfig.from_parameters(with_targets(
        grid=GRID, board=CHARUCO, plate={"type": "tag", "tag_id": 7, "tag_size": 0.2}))
    assert c.x_names == ("tag_0", "tag_1", "tag_2", "grid", "board", "plate")
    grid, board, plate = c.targets.specs
    assert grid.board == AprilGridSpec(3, 4, tag_size=0.06, tag_spacing=0.3, first_id=100,
                                       family="tag36h11", border_bits=2)
    assert board.board == CharucoSpec(5, 4, square_size=0.08, marker_size=0.06,
                                      dictionary="DICT_4X4_250")
    assert (plate.tag_id, plate.tag_size, plate.board) == (7, 0.2, None)
    assert grid.min_corners == board.min_corners == 8  # the default
    assert c.published_frames()["grid"] == ("world", "grid_calibrated")
    # round trip through the flat parameters
    assert CalibratorConfig.from_parameters(c.to_parameters()) == c


def test_only_boards_needs_no_tag_ids():
    p = with_targets(board=CHARUCO)
    del p["tags.ids"], p["tags.default_size"]
    c = CalibratorConfig.from_parameters(p)
    assert c.x_names == ("board",)
    p["targets.names"] = []
    for key in [k for k in p if k.startswith("targets.board.")]:
        del p[key]
    with pytest.raises(ValueError, match=r"^tags.ids: at least one target"):
        CalibratorConfig.from_parameters(p)


def test_min_corners_default_is_capped_by_a_small_board():
    small = dict(CHARUCO, squares_x=3, squares_y=3)  # 4 chessboard corners
    c = CalibratorConfig.from_parameters(with_targets(b=small))
    assert c.targets.specs[0].min_corners == 4
    c = CalibratorConfig.from_parameters(with_targets(b=dict(CHARUCO, min_corners=6)))
    assert c.targets.specs[0].min_corners == 6


@pytest.mark.parametrize("targets, param, words", [
    # layouts
    ({"g": dict(GRID, rows=0)}, "targets.g.rows", "must be >= 1, got 0"),
    ({"g": dict(GRID, tag_size=-0.06)}, "targets.g.tag_size", "> 0, got -0.06"),
    ({"g": dict(GRID, spacing=0.01)}, "targets.g.spacing", "invalid aprilgrid layout"),
    ({"g": dict(GRID, border_bits=0)}, "targets.g.border_bits", ">= 1, got 0"),
    ({"g": dict(GRID, first_id=580)}, "targets.g.first_id", "exceeds the 587 markers"),
    ({"c": dict(CHARUCO, squares_x=1)}, "targets.c.squares_x", ">= 2, got 1"),
    ({"c": dict(CHARUCO, marker_size=0.09)}, "targets.c.marker_size",
     "must be smaller than square_size"),
    ({"c": dict(CHARUCO, min_corners=3)}, "targets.c.min_corners", ">= 4, got 3"),
    ({"c": dict(CHARUCO, min_corners=13)}, "targets.c.min_corners", "exceeds the 12 corners"),
    # unknown dictionary / family / type
    ({"c": dict(CHARUCO, dictionary="DICT_9X9_50")}, "targets.c.dictionary",
     "unknown dictionary 'DICT_9X9_50'"),
    ({"g": dict(GRID, family="tag99h1")}, "targets.g.family", "unknown family 'tag99h1'"),
    ({"g": dict(GRID, type="checkerboard")}, "targets.g.type", "'checkerboard'"),
    # keys of another type, missing keys
    ({"g": dict(GRID, squares_x=4)}, "targets.g.squares_x", "not a parameter of a 'aprilgrid'"),
    ({"c": dict(CHARUCO, rows=4)}, "targets.c.rows", "not a parameter of a 'charuco'"),
    ({"g": {"type": "aprilgrid", "rows": 2, "cols": 2}}, "targets.g.tag_size", "missing"),
    ({"t": {"type": "tag", "tag_id": 9}}, "targets.t.tag_size", "missing"),
    # ids: a board over the single tags (tags.ids 0..2 of tag36h11), two boards, a tag target
    ({"g": dict(GRID, first_id=0)}, "targets.g.first_id",
     r"marker ids \[0, 1, 2\] of tag36h11 are used by tags.ids"),
    ({"g": GRID, "h": dict(GRID, first_id=110)}, "targets.h.first_id",
     r"marker ids \[110, 111\] of tag36h11 are used by target 'g'"),
    ({"t": {"type": "tag", "tag_id": 2, "tag_size": 0.1}}, "targets.t.tag_id",
     r"\[2\] of tag36h11 are used by tags.ids too"),
    ({"a": CHARUCO, "b": dict(CHARUCO, first_id=5)}, "targets.b.first_id",
     r"used by target 'a'"),
    ({"t": {"type": "tag", "tag_id": 600, "tag_size": 0.1}}, "targets.t.tag_id",
     "not in tag36h11"),
    # names
    ({"tag_1": CHARUCO}, "targets.names", "name of a tag frame"),
    ({"cam0": CHARUCO}, "targets.names", "name of a camera"),
    ({"9x": CHARUCO}, r"targets.names\[0\]", "not a valid name"),
])
def test_bad_targets_name_the_parameter_and_value(targets, param, words):
    with pytest.raises(ValueError, match=rf"^{param}: .*{words}"):
        CalibratorConfig.from_parameters(with_targets(**targets))


def test_boards_in_another_dictionary_may_reuse_ids():
    # ChArUco markers 0.. of DICT_4X4_250 do not collide with AprilTags 0..2 of tag36h11
    c = CalibratorConfig.from_parameters(with_targets(board=dict(CHARUCO, first_id=0)))
    assert c.targets.specs[0].marker_ids()[:3] == (0, 1, 2)


def test_parameters_of_an_unlisted_target_are_unknown():
    p = with_targets(board=CHARUCO)
    p["targets.other.type"] = "charuco"
    with pytest.raises(ValueError, match=r"^targets.other.type: unknown parameter.*"
                                         r"target 'other' is not in targets.names"):
        CalibratorConfig.from_parameters(p)


def test_priors_may_name_a_board():
    p = with_targets(board=CHARUCO)
    p.update({"priors.frames": ["board"], "priors.axes": ["z"], "priors.values_m": [1.0]})
    assert CalibratorConfig.from_parameters(p).priors.entries == (("board", "z", 1.0),)


# --- chessboards and circle grids ---------------------------------------------------------------
CHESS = {"type": "chessboard", "cols": 9, "rows": 6, "square_size": 0.03}
ORIGIN_GRID = {"type": "circles", "cols": 10, "rows": 10, "circle_spacing": 0.0254,
               "origin_circle": True}
ACIRCLES = {"type": "asymmetric_circles", "cols": 4, "rows": 11, "circle_spacing": 0.02,
            "circle_diameter": 0.015}


def test_chessboards_and_circle_grids_round_trip():
    from rwhec_ros.vision.grids import ChessboardSpec, CircleGridSpec

    c = CalibratorConfig.from_parameters(with_targets(cb=CHESS, dots=ORIGIN_GRID, ac=ACIRCLES))
    cb, dots, ac = c.targets.specs
    assert cb.board == ChessboardSpec(9, 6, 0.03) and cb.kind == "chessboard"
    assert dots.board == CircleGridSpec(10, 10, 0.0254, origin_circle=True)
    assert ac.board == CircleGridSpec(4, 11, 0.02, asymmetric=True, diameter=0.015)
    assert (dots.kind, ac.kind) == ("circles", "asymmetric_circles")
    assert cb.marker_ids() == () and not cb.has_markers
    assert CalibratorConfig.from_parameters(c.to_parameters()) == c


@pytest.mark.parametrize("targets,param,words", [
    ({"cb": {**CHESS, "rows": 9}}, "targets.cb.cols",
     "square grid.*turned by 90 degrees.*different numbers of squares"),
    ({"dots": {**ORIGIN_GRID, "origin_circle": False}}, "targets.dots.origin_circle",
     "turned by 90 degrees.*origin_circle: true"),
    ({"ac": {**ACIRCLES, "rows": 10}}, "targets.ac.rows", "odd number of rows"),
    ({"ac": {**ACIRCLES, "circle_diameter": 0.03}}, "targets.ac.circle_diameter",
     "smaller than the distance"),
    ({"cb": {**CHESS, "spacing": 0.3}}, "targets.cb.spacing", "not a parameter of a 'chessboard'"),
    ({"ac": {**ACIRCLES, "origin_circle": True}}, "targets.ac.origin_circle",
     "not a parameter of a 'asymmetric_circles'"),
    ({"cb": {"type": "chessboard", "cols": 9, "rows": 6}}, "targets.cb.square_size", "missing"),
    # two plain boards, one's pattern inside the other's (either way round): refused
    ({"cb": CHESS, "cb2": {**CHESS, "cols": 7, "rows": 5}}, "targets.names",
     "'cb' \\(9 x 6\\) and 'cb2' \\(7 x 5\\).*fits inside.*markers"),
    ({"cb": CHESS, "cb2": {**CHESS, "cols": 5, "rows": 8}}, "targets.names", "fits inside"),
    ({"dots": ORIGIN_GRID, "dots2": ORIGIN_GRID}, "targets.names", "fits inside"),
])
def test_bad_grids_name_the_parameter_the_reason_and_the_fix(targets, param, words):
    with pytest.raises(ValueError, match=rf"^{param}: .*{words}"):
        CalibratorConfig.from_parameters(with_targets(**targets))


def test_plain_boards_that_cannot_fit_inside_each_other_are_accepted():
    """9 x 6 and 7 x 8 chessboards (neither inside the other), a chessboard with a circle grid,
    and a chessboard with a ChArUco board of any size: accepted."""
    c = CalibratorConfig.from_parameters(with_targets(
        cb=CHESS, cb2={**CHESS, "cols": 7, "rows": 8}, dots=ORIGIN_GRID, ac=ACIRCLES))
    assert [t.name for t in c.targets.specs] == ["cb", "cb2", "dots", "ac"]


def test_detection_gate_and_chessboard_refinement_are_checked():
    p = minimal()
    c = CalibratorConfig.from_parameters(p)
    assert (c.detection.reprojection_gate_factor, c.detection.chessboard_refinement) == (4.0, "sb")
    p.update({"detection.reprojection_gate_factor": 0.5})
    with pytest.raises(ValueError, match=r"^detection.reprojection_gate_factor: must be finite "
                                         r"and >= 1, got 0.5"):
        CalibratorConfig.from_parameters(p)
    p = minimal()
    p["detection.chessboard_refinement"] = "classic"
    with pytest.raises(ValueError, match=r"^detection.chessboard_refinement: must be one of"):
        CalibratorConfig.from_parameters(p)


def test_a_turn_symmetric_chessboard_is_accepted_and_its_views_turned_by_the_stream():
    """The ROS tutorial's 8 x 6 board (9 x 7 squares) loads; the session's accumulator turns
    its views (test/sync/test_board_turns.py, test/test_board_turns_session.py)."""
    c = CalibratorConfig.from_parameters(with_targets(cb={**CHESS, "cols": 8}))
    cb = {t.name: t for t in c.target_specs()}["cb"]
    assert cb.turn_symmetric and cb.board.pattern_size == (8, 6)
    assert not {t.name: t for t in CalibratorConfig.from_parameters(
        with_targets(cb=CHESS)).target_specs()}["cb"].turn_symmetric
