"""The result YAML is written with libyaml's emitter where PyYAML has it: the same text as the
pure-Python ``yaml.safe_dump`` (what earlier versions wrote), and it loads back."""

from __future__ import annotations

import math

import yaml

from rwhec_ros.data.results import dump_document


def _document() -> dict:
    return {
        "verdict": "caution",
        "reasons": ["CAUTION: tag_4: not calibrated: every edge of this tag was left out "
                    "((tag_4, cam2): 1 pairs < min_pairs=3); record more views of it with "
                    "rotation about two axes", "a: b # not a comment", "'quoted' \"both\""],
        "certified": True,
        "suboptimality_bound": 4.154948593758978e-07,
        "frames": [{"name": "tag_0", "matrix": [[-0.001472186152585412, 0.08, -0.99],
                                                 [1.0, 0.0, 1e-300]], "std": [math.inf, -0.0]}],
        "empty": {}, "none": None, "unicode": "±6.7 mm, 0.43°",
        "nested": {"a": [1, 2, {"b": [True, False]}], "c": ""},
    }


def test_same_text_as_safe_dump_and_round_trip():
    doc = _document()
    text = dump_document(doc)
    assert text == yaml.safe_dump(doc, sort_keys=False)
    back = yaml.safe_load(text)
    assert back["frames"][0]["matrix"] == doc["frames"][0]["matrix"]
    assert back["reasons"] == doc["reasons"] and back["unicode"] == doc["unicode"]
    assert list(back) == list(doc)  # key order kept
