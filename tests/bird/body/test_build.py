"""The dove's generators reproduce the bundled files: bird_mjcf/dove.xml byte for byte, and the
synthetic capture's every array and provenance string.

Exact equality is the right test: each bundled file is its generator's output (the XML's header
and the capture's ``generator`` entry say so), so any difference means one was changed without
the other. The capture is compared entry by entry rather than as bytes because a zip archive
records when each member was written.
"""

from __future__ import annotations

import numpy as np
import pytest

from flapsim.bird.body import build
from flapsim.bird.flight.capture import CAPTURE_FILES
from flapsim.bird.flight.synthetic_capture import write_reference
from flapsim.core.assets import asset_dir


def test_the_generator_rewrites_the_bundled_dove_unchanged(tmp_path):
    path = build.write(tmp_path / "dove.xml")
    assert path.read_bytes() == (asset_dir("bird_mjcf") / "dove.xml").read_bytes()


@pytest.mark.parametrize("preset", ["slow", "cruise"])
def test_the_synthetic_capture_generator_rewrites_the_bundled_captures_unchanged(tmp_path, preset):
    write_reference(tmp_path / "capture.npz", seed=2013, preset=preset)
    with np.load(tmp_path / "capture.npz", allow_pickle=False) as new, \
            np.load(CAPTURE_FILES[preset], allow_pickle=False) as bundled:
        assert sorted(new.files) == sorted(bundled.files)
        for key in bundled.files:
            assert new[key].dtype == bundled[key].dtype, key
            assert np.array_equal(new[key], bundled[key]), key
