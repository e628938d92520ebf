"""The configuration reference page: generated from the specs, committed, and kept in step."""

from __future__ import annotations

import html
import re
from pathlib import Path

from rwhec_ros.config.live_parameters import live_effect
from rwhec_ros.config.reference import (
    REFERENCE_PATH,
    REGENERATE_COMMAND,
    main,
    parameter_row,
    parameter_unit,
    reference_specs,
    render_reference,
)
from rwhec_ros.config.specs import CAMERA_SPECS, GLOBAL_SPECS, TARGET_SPECS, ParamSpec

REPO = Path(__file__).resolve().parents[1]
_ROW_RE = re.compile(r"^\| `([^`]+)` \| (.*) \|$")


def _rows(page: str) -> dict[str, list[str]]:
    """Parameter name -> its cells after the name, from every table row of ``page``; a name
    that appears twice fails."""
    rows: dict[str, list[str]] = {}
    for line in page.splitlines():
        m = _ROW_RE.match(line)
        if m:
            assert m.group(1) not in rows, f"{m.group(1)} has two rows"
            rows[m.group(1)] = re.split(r" \| ", m.group(2))
    return rows


def test_committed_reference_matches_the_specs():
    """The committed page is exactly what the specs render to: change specs.py, regenerate."""
    path = REPO / REFERENCE_PATH
    assert path.is_file(), f"{REFERENCE_PATH} is missing: write it with {REGENERATE_COMMAND}"
    committed = path.read_text(encoding="utf-8")
    assert committed == render_reference(), (
        f"{REFERENCE_PATH} is out of date with rwhec_ros/config/specs.py: regenerate it with "
        f"`{REGENERATE_COMMAND}` (from the repository root) and commit it")


def test_every_parameter_has_one_row_with_type_default_and_meaning():
    """Each parameter of the schema appears once, under its section, with its type, default and
    description as the spec states them; the page names no other parameter."""
    page = render_reference()
    rows = _rows(page)
    specs = {s.name: s for s in reference_specs()}
    n_globals = len(GLOBAL_SPECS)
    # + 1: sync.time_offset.<name>
    assert len(specs) == n_globals + len(CAMERA_SPECS) + len(TARGET_SPECS) + 1
    assert set(rows) == set(specs)
    kinds = {"int_array": "int[]", "double_array": "double[]", "string_array": "string[]",
             "int_or_auto": 'int or `"auto"`'}
    for name, spec in specs.items():
        kind, default, _unit, _live, meaning = rows[name]
        assert kind == kinds.get(spec.kind, spec.kind), name
        if spec.required:
            assert default == "**required**", name
        elif spec.default is None:
            assert default == "unset", name
        else:
            assert default.startswith("`") and default.endswith("`"), name
        # the meaning is the spec's doc, HTML-escaped for the table
        assert html.unescape(meaning.replace("\\|", "|")) == spec.doc, name
    # sections: a parameter's row sits under the heading of its first name part
    section = None
    for line in page.splitlines():
        if line.startswith("## "):
            section = line[3:]
        m = _ROW_RE.match(line)
        if m:
            assert m.group(1).split(".")[0] == section, m.group(1)


def test_specific_rows():
    """A few rows written out: required, unset, a tuple default, an escaped placeholder."""
    rows = {s.name: parameter_row(s) for s in reference_specs()}
    assert rows["solver.min_pairs"] == (
        "| `solver.min_pairs` | int | `3` |  | live | edges with fewer pairs are left out |")
    assert rows["tags.default_size"].startswith(
        "| `tags.default_size` | double | unset | m | restart | ")
    assert rows["priors.values_m"].startswith("| `priors.values_m` | double[] | `[]` | m | live |")
    assert rows["cameras.<name>.image_topic"] == (
        "| `cameras.<name>.image_topic` | string | **required** |  | restart | "
        "sensor_msgs/Image topic |")
    assert "&lt;tags.frame_prefix&gt;&lt;id&gt;" in rows["tags.ids"]
    odd = ParamSpec("x.y", "string", "a", doc="a|b <c> & d")
    assert parameter_row(odd).endswith("| a\\|b &lt;c&gt; &amp; d |")


def test_units_from_name_suffix_or_description():
    by_name = {s.name: s for s in reference_specs()}
    assert parameter_unit(by_name["keyframe.min_rotation_rad"]) == "rad"
    assert parameter_unit(by_name["detection.max_obliquity_deg"]) == "deg"
    assert parameter_unit(by_name["ros.detections_rate_hz"]) == "Hz"
    assert parameter_unit(by_name["noise.sigma"]) == "m"  # "[m]" in its description
    assert parameter_unit(by_name["noise.kappa"]) == ""
    assert parameter_unit(by_name["solver.min_pairs"]) == ""
    assert parameter_unit(ParamSpec("a.b", "double", 1.0, doc="wait [s] for it")) == "s"


def test_run_time_column_follows_the_live_parameters():
    """``live`` exactly where the node's parameter callback accepts a change."""
    for spec in reference_specs():
        cells = parameter_row(spec).split(" | ")
        assert cells[4] == ("live" if live_effect(spec.name) is not None else "restart"), spec.name
    rows = _rows(render_reference())
    assert rows["solver.mode"][3] == "live"
    assert rows["cameras.names"][3] == "restart"


def test_write_and_check_entry_point(tmp_path, capsys):
    page = tmp_path / "reference.md"
    assert main(["--check", str(page)]) == 1  # missing
    assert REGENERATE_COMMAND in capsys.readouterr().err
    assert main(["--write", str(page)]) == 0
    assert page.read_text(encoding="utf-8") == render_reference()
    assert main(["--check", str(page)]) == 0
    page.write_text(render_reference().replace("| `3` |", "| `4` |"), encoding="utf-8")
    assert main(["--check", str(page)]) == 1
    err = capsys.readouterr().err
    assert "out of date" in err and REGENERATE_COMMAND in err
    assert main([]) == 0
    assert capsys.readouterr().out == render_reference()
