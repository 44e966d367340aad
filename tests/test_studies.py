"""Every study in studies/ still imports and still parses its options.

The studies live outside the package and nothing else runs them; this keeps them from rotting
silently when a module they use moves or changes. Each study is imported as a module (its
``main`` does not run) and its argument parser answers ``--help``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

STUDIES = sorted((Path(__file__).resolve().parent.parent / "studies").glob("*.py"))


def test_the_studies_folder_is_found():
    assert len(STUDIES) >= 10


@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_each_study_imports_and_answers_help(path, capsys):
    spec = importlib.util.spec_from_file_location(f"study_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.__doc__ and "python studies/" + path.name in module.__doc__, \
        "the docstring says what the study measures and the command that runs it"
    with pytest.raises(SystemExit) as exit_:
        module.parser().parse_args(["--help"])
    assert exit_.value.code == 0
    assert "usage:" in capsys.readouterr().out
