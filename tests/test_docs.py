"""The README and docs/ stay usable: every ``flapsim`` command in their ``bash`` blocks parses
with today's command line, and every section a source file, script, test or document cites
by name (``docs/flight_log.md, "Speed first"``) exists in the file it names. Both rot
silently otherwise: an option renamed or a section moved leaves a user with a command that
fails or a pointer to nothing (session 28 moved most of the README into docs/)."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from flapsim.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# `docs/x.md, "Name"`, `[docs/x.md](docs/x.md), "Name"`, `x.md), "A" and "B"`
_CITE = re.compile(r'\[?((?:docs/)?[a-z_]+\.md)(?:\]\([^)]*\))?\)?,\s*(?:sections?\s+)?'
                   r'"([^"]+)"((?:\s*(?:,|and|or)\s*"[^"]+")*)')


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
    # the README alone shows ~25 and the docs ~60: a regex that found none would pass vacuously
    assert len(commands) >= 60
    bad = [(name, c, msg) for name, c in commands if (msg := _parses(c)) is not None]
    assert not bad, bad


def test_the_command_check_rejects_what_the_command_line_does_not_take():
    # the check above must be able to fail: an unknown option, a missing value, a bad choice
    assert _parses("flapsim eval --scenario figure8 --bogus") is not None
    assert _parses("flapsim swim --figure8") is not None
    assert _parses("flapsim swim --layers most") is not None
    assert _parses("flapsim eval --scenario figure8 --plots out") is None


def test_every_cited_section_exists():
    sources = [*ROOT.glob("flapsim/**/*.py"), *ROOT.glob("scripts/**/*.py"),
               *ROOT.glob("tests/**/*.py"), *DOCS]
    cites = [(src, f, name) for src in sources if src.name != "test_docs.py"
             for f, name in _citations(src)]
    assert len(cites) >= 25  # the package alone cites the flight log ~20 times
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


@pytest.mark.parametrize("text, found", [
    ('(docs/flight_log.md, "Speed first")', [("docs/flight_log.md", "Speed first")]),
    ('#: (docs/flight_log.md, "Carrying the last\n#: wingbeat" and "More angle")',
     [("docs/flight_log.md", "Carrying the last wingbeat"), ("docs/flight_log.md", "More angle")]),
    ('[docs/flight.md](docs/flight.md), "Path following"', [("docs/flight.md", "Path following")]),
])
def test_citations_are_found_across_lines_and_links(tmp_path, text, found):
    p = tmp_path / "x.py"
    p.write_text(text)
    assert _citations(p) == found
