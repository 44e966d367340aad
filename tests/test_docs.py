"""The README and docs/ stay usable: every ``flapsim`` command in their ``bash`` blocks parses
with today's command line, every section a source file, study, test or document cites by name
(``docs/design/flight.md, "Speed first"``) exists in the file it names, and every relative
link leads to a file. Both rot silently otherwise: an option renamed or a section moved leaves
a user with a command that fails or a pointer to nothing. The README stays short (150 lines at
most) and the manual speaks of the project only: no session or issue numbers."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from flapsim.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

# `docs/x.md, "Name"`, `[docs/design/x.md](design/x.md), "Name"`, `x.md), "A" and "B"`
_CITE = re.compile(r'\[?((?:docs/)?(?:design/)?[a-z_]+\.md)(?:\]\([^)]*\))?\)?,\s*'
                   r'(?:sections?\s+)?"([^"]+)"((?:\s*(?:,|and|or)\s*"[^"]+")*)')


def _commands(text: str) -> list[str]:
    """The ``flapsim ...`` invocations of a Markdown text's ``bash`` blocks."""
    found = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.replace("\\\n", " ").split("\n"):
            line = line.split(" #")[0].strip()
            for part in re.split(r"&&|;", "" if line.startswith("#") else line):
                if part.strip().startswith("flapsim "):
                    found.append(part.strip())
    return found


def _parses(command: str) -> str | None:
    """None if ``command`` parses, else argparse's message."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(shlex.split(command)[1:])
    except SystemExit as e:
        if e.code:
            return err.getvalue().strip() or f"exit {e.code}"
    return None


def _sections(md: Path) -> list[str]:
    """Headings and bold run-in headings (``**Speed first.**``) of a Markdown file."""
    text = md.read_text(encoding="utf-8")
    return (re.findall(r"^#+\s+(.+?)\s*$", text, re.M)
            + re.findall(r"\*\*([^*]+?)\*\*", text))


def _citations(path: Path) -> list[tuple[str, str]]:
    """(file, section) pairs ``path`` cites, comment markers and line breaks flattened."""
    text = re.sub(r"\n\s*(?:#:?|\*|-)?\s*", " ", path.read_text(encoding="utf-8"))
    out = []
    for m in _CITE.finditer(text):
        names = [m.group(2), *re.findall(r'"([^"]+)"', m.group(3))]
        out += [(m.group(1), n) for n in names]
    return out


def _resolve(cited: str) -> Path:
    return ROOT / cited if cited.startswith("docs/") or cited == "README.md" else ROOT / "docs" / cited


def test_every_command_in_the_readme_and_docs_parses():
    commands = [(md.name, c) for md in DOCS for c in _commands(md.read_text(encoding="utf-8"))]
    # the README shows ~10 and the docs ~45: a regex that found none would pass vacuously
    assert len(commands) >= 40
    bad = [(name, c, msg) for name, c in commands if (msg := _parses(c)) is not None]
    assert not bad, bad


def test_the_command_check_rejects_what_the_command_line_does_not_take():
    # the check above must be able to fail: an unknown option, a missing value, a bad choice
    assert _parses("flapsim eval --scenario figure8 --bogus") is not None
    assert _parses("flapsim swim --figure8") is not None
    assert _parses("flapsim swim --layers most") is not None
    assert _parses("flapsim eval --scenario figure8 --plots out") is None


def test_every_cited_section_exists():
    sources = [*ROOT.glob("flapsim/**/*.py"), *ROOT.glob("studies/**/*.py"),
               *ROOT.glob("tests/**/*.py"), *DOCS]
    cites = [(src, f, name) for src in sources if src.name != "test_docs.py"
             for f, name in _citations(src)]
    assert len(cites) >= 5  # the README and the docs cite each other's sections
    sections = {}
    bad = []
    for src, f, name in cites:
        target = _resolve(f)
        if not target.exists():
            bad.append((src.relative_to(ROOT).as_posix(), f, name, "no such file"))
            continue
        heads = sections.setdefault(target, _sections(target))
        want = name.rstrip(".")
        if not any(h.rstrip(".").startswith(want) for h in heads):
            bad.append((src.relative_to(ROOT).as_posix(), f, name, "no such section"))
    assert not bad, bad


def test_every_section_the_docs_point_to_by_name_exists():
    # the docs also say 'see "Speed first"' without a file: the section is in one of them
    heads = [h.rstrip(".") for md in DOCS for h in _sections(md)]
    bad = []
    for md in DOCS:
        text = re.sub(r"\n\s*", " ", md.read_text(encoding="utf-8"))
        for m in re.finditer(r'(?:see|in|above|below)\s+"([^"]{6,})"', text):
            if not any(h.startswith(m.group(1).rstrip(".")) for h in heads):
                bad.append((md.name, m.group(1)))
    assert not bad, bad


def test_every_relative_link_in_the_docs_leads_to_a_file():
    # links resolve from the Markdown file's own folder, as GitHub renders them
    links = [(md, link) for md in DOCS
             for link in re.findall(r"\]\(([^)#:]+?)(?:#[^)]*)?\)", md.read_text(encoding="utf-8"))]
    assert len(links) >= 5
    bad = [(md.name, link) for md, link in links if not (md.parent / link).exists()]
    assert not bad, bad


def test_the_readme_is_short():
    # a front page, not the manual: what it is, install, the quickstart, a tour, links
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert 40 <= len(lines) <= 150, len(lines)


_DIARY = re.compile(r"session [0-9]|issue #?[0-9]|\bxeon\b|\bepyc\b", re.I)


def test_the_manual_names_no_session_issue_or_processor():
    # facts and how to reproduce them, not when or on which machine they were measured
    bad = [(md.relative_to(ROOT).as_posix(), i, line.strip())
           for md in DOCS for i, line in enumerate(md.read_text(encoding="utf-8").splitlines(), 1)
           if _DIARY.search(line)]
    assert not bad, bad


def test_the_manual_check_finds_a_session_an_issue_and_a_processor():
    # built from parts, so that a grep of the repository for them does not find this test
    session, issue = "session", "issue"
    for text in (f"measured in {session} 28", f"see {issue} #14", f"{issue.title()} 4's targets",
                 "on the AMD " + "EPYC"):
        assert _DIARY.search(text), text
    assert not _DIARY.search("the 2 m tube at wingbeat 14, seed 2")


@pytest.mark.parametrize("text, found", [
    ('(docs/design/flight.md, "Speed first")', [("docs/design/flight.md", "Speed first")]),
    ('#: (docs/design/flight.md, "Carrying the last\n#: wingbeat" and "More angle")',
     [("docs/design/flight.md", "Carrying the last wingbeat"), ("docs/design/flight.md", "More angle")]),
    ('[docs/flight.md](docs/flight.md), "Path following"', [("docs/flight.md", "Path following")]),
    ('[docs/design/swimming.md](design/swimming.md), "The strokes"',
     [("docs/design/swimming.md", "The strokes")]),
])
def test_citations_are_found_across_lines_and_links(tmp_path, text, found):
    p = tmp_path / "x.py"
    p.write_text(text)
    assert _citations(p) == found
