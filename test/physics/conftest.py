"""Shared physics fixtures."""

import pytest

from hair_sim import load_hairstyle, paths


@pytest.fixture(scope='session')
def long_style():
    """Load the thesis' sample (long) style."""
    return load_hairstyle(paths.shipped_style('thesis_long'))
