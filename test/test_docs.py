"""The documentation: every relative link in README.md and docs/*.md resolves, to a file and, for
``#anchor`` links, to a heading of it (GitHub's anchor rules); README.md stays a front page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: The front page's length limit (issue 31: "a front page of at most ~250 lines").
README_MAX_LINES = 260

_FENCE_RE = re.compile(r"^\s*(```|~~~)")
_HEADING_RE = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
_CODE_SPAN_RE = re.compile(r"(`+)(.*?)\1")
_LINK_RE = re.compile(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
_REF_DEF_RE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s+<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$")
_HTML_ANCHOR_RE = re.compile(r"<a\s+(?:[^>]*\s)?(?:id|name)=\"([^\"]+)\"", re.IGNORECASE)
_SCHEME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


def doc_files() -> list[Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def _prose_lines(text: str):
    """(line number, line) outside fenced code blocks."""
    fenced = False
    for i, line in enumerate(text.splitlines(), 1):
        if _FENCE_RE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            yield i, line


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: the rendered text (code spans and link texts kept,
    their markup dropped), lowercased, every character that is not a letter, a digit, a space,
    ``-`` or ``_`` removed, spaces replaced by ``-``."""
    text = _CODE_SPAN_RE.sub(lambda m: m.group(2), heading)
    text = _LINK_RE.sub(lambda m: m.group(1), text)
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML tags
    text = text.strip().lower()
    text = "".join(ch for ch in text if ch.isalnum() or ch in " -_")
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor of a Markdown file: its headings (a repeated heading gets ``-1``, ``-2``, ...)
    and explicit ``<a id="...">`` / ``<a name="...">`` anchors."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    for _, line in _prose_lines(path.read_text(encoding="utf-8")):
        m = _HEADING_RE.match(line)
        if m:
            base = github_anchor(m.group(2))
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
        out.update(_HTML_ANCHOR_RE.findall(line))
    return out


def links(path: Path) -> list[tuple[int, str]]:
    """(line, target) of every inline link, image and reference definition outside code."""
    out = []
    for i, line in _prose_lines(path.read_text(encoding="utf-8")):
        prose = _CODE_SPAN_RE.sub("", line)
        out += [(i, m.group(2)) for m in _LINK_RE.finditer(prose)]
        m = _REF_DEF_RE.match(prose)
        if m:
            out.append((i, m.group(1)))
    return out


def broken_links(path: Path) -> list[str]:
    """The relative links of ``path`` whose file or anchor does not exist, in words."""
    problems = []
    for line, target in links(path):
        if not target or _SCHEME_RE.match(target) or target.startswith("//"):
            continue  # absolute URLs (https:, mailto:) are not checked here
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path
        where = f"{path.relative_to(REPO) if path.is_relative_to(REPO) else path}:{line}"
        if not dest.exists():
            problems.append(f"{where}: {target}: no file {file_part}")
            continue
        if anchor:
            if dest.suffix != ".md" or dest.is_dir():
                problems.append(f"{where}: {target}: an anchor into a file that is not Markdown")
            elif anchor not in anchors(dest):
                problems.append(f"{where}: {target}: no heading with anchor #{anchor} in "
                                f"{dest.name}")
    return problems


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: p.name)
def test_relative_links_resolve(path):
    assert path.is_file()
    assert broken_links(path) == []


def test_readme_is_a_front_page():
    n = len((REPO / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, (
        f"README.md has {n} lines, more than {README_MAX_LINES}: move the detail into docs/")


def test_every_docs_page_is_reachable_from_the_readme():
    """Following relative links from README.md reaches every docs/*.md page."""
    reached = {REPO / "README.md"}
    todo = [REPO / "README.md"]
    while todo:
        page = todo.pop()
        for _, target in links(page):
            if _SCHEME_RE.match(target) or not target.split("#")[0]:
                continue
            dest = (page.parent / target.split("#")[0]).resolve()
            if dest.suffix == ".md" and dest.is_file() and dest not in reached:
                reached.add(dest)
                todo.append(dest)
    missing = [p.name for p in sorted((REPO / "docs").glob("*.md")) if p.resolve() not in reached]
    assert missing == [], f"docs pages no link from README.md leads to: {missing}"


# --- the checker itself ----------------------------------------------------------------------


@pytest.mark.parametrize("heading, anchor", [
    ("Quick start (no ROS needed)", "quick-start-no-ros-needed"),
    ("Can I trust my calibration? The verdict", "can-i-trust-my-calibration-the-verdict"),
    ("Reading `/diagnostics`", "reading-diagnostics"),
    ("The numpy-1.26 line", "the-numpy-126-line"),
    ("camera_carrier", "camera_carrier"),
    ("Offline CLI: rwhec-calibrate", "offline-cli-rwhec-calibrate"),
    ("A [linked](x.md) heading", "a-linked-heading"),
    ("Keyframes and memory", "keyframes-and-memory"),
])
def test_github_anchor_rules(heading, anchor):
    assert github_anchor(heading) == anchor


def test_checker_finds_broken_files_and_anchors(tmp_path):
    (tmp_path / "other.md").write_text("# Other page\n\n## A section: here\n\n## A section: here\n"
                                       "<a id=\"custom\"></a>\n", encoding="utf-8")
    page = tmp_path / "page.md"
    page.write_text(
        "# Page\n\n"
        "[ok](other.md) [ok](other.md#a-section-here) [ok](other.md#a-section-here-1) "
        "[ok](other.md#custom) [ok](#page) [ok](https://example.com/missing.md)\n"
        "[bad file](missing.md) [bad anchor](other.md#nowhere) [bad self](#nothing)\n"
        "`[in code](missing2.md)`\n\n```\n[in a block](missing3.md)\n# not a heading\n```\n"
        "[bad block heading](#not-a-heading)\n",
        encoding="utf-8")
    problems = broken_links(page)
    assert len(problems) == 4, problems
    assert any("no file missing.md" in p for p in problems)
    assert any("#nowhere" in p for p in problems)
    assert any("#nothing" in p for p in problems)
    assert any("#not-a-heading" in p for p in problems)
