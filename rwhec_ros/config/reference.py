"""The configuration reference (``docs/configuration-reference.md``), rendered from the schema.

The page is generated, never edited by hand: :data:`~.specs.GLOBAL_SPECS`,
:data:`~.specs.CAMERA_SPECS` and :data:`~.specs.TARGET_SPECS` are the one source of every
parameter's name, type, default and description, and :mod:`.live_parameters` of what
``ros2 param set`` may change while the node runs. One table per section (the first part of the
dotted name), in the order of the schema. Regenerate the committed page after changing the
schema::

    python -m rwhec_ros.config.reference --write     # writes docs/configuration-reference.md
    python -m rwhec_ros.config.reference --check     # exit 1 if the committed page is stale
    python -m rwhec_ros.config.reference             # the page on stdout

``test/test_config_reference.py`` fails when the committed page and the schema disagree.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from .live_parameters import live_effect
from .specs import CAMERA_SPECS, GLOBAL_SPECS, TARGET_SPECS, TIME_OFFSET_SPEC, ParamSpec

__all__ = [
    "REFERENCE_PATH",
    "REGENERATE_COMMAND",
    "reference_specs",
    "parameter_unit",
    "parameter_row",
    "render_reference",
    "main",
]

#: Where the page lives, relative to the repository root.
REFERENCE_PATH = "docs/configuration-reference.md"
#: The command that rewrites it (run from the repository root).
REGENERATE_COMMAND = "python -m rwhec_ros.config.reference --write"

#: Type column: the spec's kind as a reader writes it in a parameter file.
_KIND_LABELS = {
    "bool": "bool",
    "int": "int",
    "double": "double",
    "string": "string",
    "int_array": "int[]",
    "double_array": "double[]",
    "string_array": "string[]",
    "int_or_auto": 'int or `"auto"`',
}

#: Unit by name suffix (the schema's convention: parameter names carry their unit).
_SUFFIX_UNITS = (("_m", "m"), ("_s", "s"), ("_rad", "rad"), ("_deg", "deg"), ("_px", "px"),
                 ("_hz", "Hz"))
#: Unit stated in a description as ``[m]`` (names without a unit suffix, e.g. ``noise.sigma``).
_DOC_UNIT_RE = re.compile(r"\[(m|s|rad|deg|px|Hz)\]")


def reference_specs() -> list[ParamSpec]:
    """Every parameter of the schema once: the global ones, then ``cameras.<name>.<key>`` and
    ``targets.<name>.<key>`` with the literal placeholder ``<name>``."""
    out = list(GLOBAL_SPECS)
    for prefix, specs in (("cameras", CAMERA_SPECS), ("targets", TARGET_SPECS)):
        out += [ParamSpec(f"{prefix}.<name>.{s.name}", s.kind, s.default, s.required, s.doc)
                for s in specs]
    t = TIME_OFFSET_SPEC
    out.append(ParamSpec(f"sync.{t.name}.<name>", t.kind, t.default, t.required, t.doc))
    return out


def parameter_unit(spec: ParamSpec) -> str:
    """The unit of a parameter: from its name's suffix (``_m``, ``_s``, ``_rad``, ``_deg``,
    ``_px``, ``_hz``), else the first ``[unit]`` in its description, else ``""``
    (dimensionless, a count, a name or a flag)."""
    for suffix, unit in _SUFFIX_UNITS:
        if spec.name.endswith(suffix):
            return unit
    m = _DOC_UNIT_RE.search(spec.doc)
    return m.group(1) if m else ""


def _default(spec: ParamSpec) -> str:
    if spec.required:
        return "**required**"
    v = spec.default
    if v is None:
        return "unset"
    if isinstance(v, bool):
        return f"`{str(v).lower()}`"
    if isinstance(v, str):
        return f'`"{v}"`'
    if isinstance(v, tuple):
        return f"`{list(v)}`"
    return f"`{v!r}`"


def _text(s: str) -> str:
    """Plain text in a table cell: HTML characters escaped (``<name>`` would vanish as a tag),
    ``|`` escaped so that it does not split the cell."""
    return (s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace("|", "\\|"))


def _live(name: str) -> str:
    return "live" if live_effect(name) is not None else "restart"


def parameter_row(spec: ParamSpec) -> str:
    """One table row: parameter, type, default, unit, run time (``live`` / ``restart``),
    meaning."""
    unit = parameter_unit(spec)
    return (f"| `{spec.name}` | {_KIND_LABELS[spec.kind]} | {_default(spec)} | "
            f"{unit} | {_live(spec.name)} | {_text(spec.doc)} |")


_HEADER = """\
# Configuration reference

<!-- Generated from rwhec_ros/config/specs.py by `{command}`; do not edit by hand. -->

Every parameter of the calibrator, for the node's parameter file and the CLI's `--config` alike
(generated from the parameter specs in `rwhec_ros/config/specs.py`; regenerate with
`{command}`). How the file is written, what is checked and the example files are in
[configuration.md](configuration.md).

Columns: the parameter's dotted name; its type (a `double` is written with a decimal point,
`1.0`, as `ros2` requires); its default (**required**: no default; unset: optional, the
documented behaviour applies); its unit (from the name's suffix `_m`, `_s`, `_rad`, `_deg`,
`_px`, `_hz`, or the `[unit]` in the meaning; empty for counts, flags, names, ratios and
concentrations); at run time: `live` when
`ros2 param set` on the running node changes it ([ros.md](ros.md#changing-parameters-at-run-time)
says when it takes effect), `restart` when the node refuses the change; its meaning.

Sections: {sections}.
"""

_TABLE_HEAD = ("| parameter | type | default | unit | at run time | meaning |\n"
               "|---|---|---|---|---|---|")


def _sections(specs: list[ParamSpec]) -> dict[str, list[ParamSpec]]:
    """Specs grouped by the first part of their dotted name, in the order of first appearance."""
    groups: dict[str, list[ParamSpec]] = {}
    for spec in specs:
        groups.setdefault(spec.name.split(".", 1)[0], []).append(spec)
    return groups


def render_reference() -> str:
    """The Markdown page: a header, then one ``## <section>`` table per section."""
    groups = _sections(reference_specs())
    links = ", ".join(f"[{name}](#{name})" for name in groups)
    parts = [_HEADER.format(command=REGENERATE_COMMAND, sections=links)]
    for name, specs in groups.items():
        parts.append(f"## {name}\n\n{_TABLE_HEAD}\n" + "\n".join(parameter_row(s) for s in specs)
                     + "\n")
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    """``python -m rwhec_ros.config.reference [--write [PATH] | --check [PATH]]``."""
    parser = argparse.ArgumentParser(
        prog="python -m rwhec_ros.config.reference",
        description="Render the configuration reference from the parameter specs "
                    "(default: to stdout).")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--write", nargs="?", const=REFERENCE_PATH, metavar="PATH",
                       help=f"write the page to PATH (default: {REFERENCE_PATH}, relative to "
                            "the current directory: run from the repository root)")
    group.add_argument("--check", nargs="?", const=REFERENCE_PATH, metavar="PATH",
                       help="exit 1 when PATH differs from the rendered page")
    args = parser.parse_args(argv)
    page = render_reference()
    if args.write is not None:
        Path(args.write).write_text(page, encoding="utf-8")
        return 0
    if args.check is not None:
        path = Path(args.check)
        try:
            current = path.read_text(encoding="utf-8")
        except OSError as e:
            print(f"{path}: cannot read it ({e.strerror}); write it with {REGENERATE_COMMAND}",
                  file=sys.stderr)
            return 1
        if current != page:
            print(f"{path} is out of date with rwhec_ros/config/specs.py; regenerate it with "
                  f"{REGENERATE_COMMAND}", file=sys.stderr)
            return 1
        return 0
    sys.stdout.write(page)
    return 0


if __name__ == "__main__":
    sys.exit(main())
