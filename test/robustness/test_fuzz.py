"""Fuzzing: the hairstyle loader and the input handlers never fail unhandled or go non-finite."""

import copy
import math

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
import yaml

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths
from hair_sim.modeling import HairstyleError, hairstyle_from_dict

BASE = yaml.safe_load(open(paths.shipped_style('bob_fringe')))
HEAD = load_hairstyle(paths.shipped_style('bob_fringe')).head

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10 ** 6, 10 ** 6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
values = st.recursive(scalars, lambda c: st.one_of(st.lists(c, max_size=6),
                                                   st.dictionaries(st.text(max_size=6), c,
                                                                   max_size=4)), max_leaves=20)


def mutate(data, path, value):
    """Set data at `path` (a list of keys/indices) to value, if the path exists."""
    node = data
    for key in path[:-1]:
        if isinstance(node, dict) and key in node:
            node = node[key]
        elif isinstance(node, list) and isinstance(key, int) and -len(node) <= key < len(node):
            node = node[key]
        else:
            return data
    last = path[-1]
    if isinstance(node, dict):
        node[last] = value
    elif isinstance(node, list) and isinstance(last, int) and -len(node) <= last < len(node):
        node[last] = value
    return data


PATHS = [['name'], ['head'], ['lod'], ['lod', 'vertices'], ['lod', 'render_rows'],
         ['lod', 'render_columns'], ['material'], ['material', 'color'],
         ['material', 'texture'], ['material', 'texture', 'width'], ['patches'],
         ['patches', 0], ['patches', 0, 'degree'], ['patches', 0, 'strips'],
         ['patches', 0, 'control_hairs'], ['patches', 0, 'control_hairs', 1],
         ['patches', 0, 'control_hairs', 1, 2], ['patches', 0, 'control_hairs', 1, 2, 0],
         ['patches', 1, 'weights'], ['patches', 1, 'knots_along'], ['root_tolerance']]


@settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(PATHS), values), min_size=1, max_size=3))
def test_loader_only_ever_raises_hairstyle_error(edits):
    """Mutated hairstyles either load (finite geometry) or raise HairstyleError."""
    data = copy.deepcopy(BASE)
    for path, value in edits:
        data = mutate(data, path, value)
    try:
        style = hairstyle_from_dict(data, head=HEAD)
    except HairstyleError:
        return
    for p in style.patches:
        assert np.all(np.isfinite(p.points))


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=300))
def test_loader_survives_arbitrary_text(tmp_path_factory, text):
    """Any text as a file: a style or HairstyleError, nothing else."""
    path = tmp_path_factory.mktemp('fuzz') / 'x.yaml'
    path.write_text(text)
    try:
        load_hairstyle(str(path))
    except HairstyleError:
        pass


finite_or_not = st.floats(allow_nan=True, allow_infinity=True, width=64)


@pytest.fixture(scope='module')
def sim():
    """One simulator for the input fuzzing (state carries over, as in a running node)."""
    return HairSimulator(load_hairstyle(paths.shipped_style('thesis_short')))


@settings(max_examples=1500, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture])
@given(stamp=finite_or_not, pos=st.lists(finite_or_not, min_size=3, max_size=3),
       quat=st.lists(finite_or_not, min_size=4, max_size=4),
       wind=st.lists(finite_or_not, min_size=3, max_size=3), turb=finite_or_not,
       seed=st.integers(-2 ** 40, 2 ** 40))
def test_input_handlers_keep_the_state_finite(sim, stamp, pos, quat, wind, turb, seed):
    """Arbitrary poses and wind: a verdict or ValueError, and the state stays finite."""
    verdict = sim.set_head_pose(stamp, pos, quat)
    assert verdict in ('ok', 'normalised', 'invalid', 'repeated', 'out_of_order',
                       'clock_jump', 'teleport')
    try:
        sim.set_wind(wind, turbulence=turb, seed=seed)
    except ValueError:
        pass
    sim.step(DEFAULT_DT)
    assert np.all(np.isfinite(sim.pos)), (stamp, pos, quat, wind)
    assert float(np.linalg.norm(sim.wind.velocity)) <= sim.params.max_wind_speed + 1e-9
    assert not math.isnan(sim.time)
