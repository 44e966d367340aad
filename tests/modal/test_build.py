"""The creature generators reproduce the bundled creatures/*.xml byte for byte.

Exact equality is the right test: each bundled file is its generator's output (the file's
header says so), so any difference means one was edited without the other.
"""

from __future__ import annotations

import pytest

from flapsim.core.assets import asset_dir
from flapsim.modal.build import creatures, dog_human


@pytest.mark.parametrize("generator", [creatures, dog_human], ids=["creatures", "dog_human"])
def test_each_generator_rewrites_the_bundled_files_unchanged(tmp_path, generator):
    written = generator.write(tmp_path)
    assert written, "the generator wrote nothing"
    for path in written:
        assert path.read_bytes() == (asset_dir("creatures") / path.name).read_bytes(), path.name


def test_the_command_line_entry_writes_into_the_folder_asked(tmp_path, capsys):
    creatures.main(["--out", str(tmp_path)])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["linear.xml", "loop.xml"]
    assert "wrote" in capsys.readouterr().out
