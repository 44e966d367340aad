"""The swimmer generator reproduces the bundled swimmer_mjcf/swimmer.xml byte for byte.

Exact equality is the right test: the bundled file is the generator's output (its header
says so), so any difference means one was edited without the other.
"""

from __future__ import annotations

from flapsim.core.assets import asset_dir
from flapsim.swim.build import swimmer


def test_the_generator_rewrites_the_bundled_swimmer_unchanged(tmp_path):
    path = swimmer.write(tmp_path / "swimmer.xml")
    assert path.read_bytes() == (asset_dir("swimmer_mjcf") / "swimmer.xml").read_bytes()


def test_the_command_line_entry_writes_the_file_asked(tmp_path, capsys):
    swimmer.main(["--out", str(tmp_path / "s.xml")])
    assert (tmp_path / "s.xml").is_file()
    assert "total mass 89.570 kg" in capsys.readouterr().out
