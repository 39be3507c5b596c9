"""Shared render fixtures."""

import pytest

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths
from hair_sim.render import HairRenderer


@pytest.fixture(scope='module')
def settled():
    """Return the sample style's simulator, settled at rest with the head upright."""
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')))
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    while not sim.sleeping:
        sim.step(DEFAULT_DT)
    return sim


@pytest.fixture(scope='module')
def renderer(settled):
    """Return the renderer of the settled sample style."""
    return HairRenderer.for_simulator(settled)
