"""Shared fixtures: every test leaves the process-wide passive callback clean."""

import pytest

from flapsim.sim.callbacks import DISPATCHER


@pytest.fixture(autouse=True)
def _clean_dispatcher():
    yield
    DISPATCHER.clear()
