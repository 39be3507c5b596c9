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


def test_a_huge_finite_wind_is_clamped_along_its_direction(sim):
    """A wind of 1e300 m/s is a gale at max_wind_speed along it, not still air."""
    assert sim.set_wind([1e300, -1e300, 0.0]) == 'clamped'
    top = sim.params.max_wind_speed
    assert np.allclose(sim.wind.velocity, [top / math.sqrt(2), -top / math.sqrt(2), 0.0],
                       rtol=1e-12, atol=0.0)
    sim.set_wind([0.0, 0.0, 0.0])


@pytest.fixture(scope='module', params=['anjyo', 'articulated'])
def placed(request):
    """One simulator per model for set_directions (state carries over)."""
    return HairSimulator(load_hairstyle(paths.shipped_style('bob_fringe')), model=request.param)


@settings(max_examples=300, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_set_directions_refuses_what_is_not_a_direction_and_keeps_the_hair(placed, data):
    """
    Arbitrary directions: placed (and the state finite after a step) or ValueError.

    The arrays are the right shape with NaN, infinities, zeros, huge or tiny numbers
    anywhere, or another shape, or not numbers. A refusal leaves the strands, their
    velocities and the step state as they were.
    """
    n, segs = placed.pos.shape[0], placed.pos.shape[1] - 1
    shape = data.draw(st.sampled_from([(n, segs, 3), (n, segs, 3), (n, segs, 3), (n, segs),
                                       (n - 1, segs, 3), (segs, 3), (n, segs, 4), ()]))
    if shape == (n, segs, 3):                    # straight down, a few numbers changed
        d = np.tile([0.0, 0.0, -1.0], (n, segs, 1))
        for _ in range(data.draw(st.integers(0, 4))):
            value = data.draw(st.one_of(finite_or_not, st.sampled_from(
                [0.0, 1e-320, 1e300, -1e300])))
            d[data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, segs - 1)),
              data.draw(st.integers(0, 2))] = value
        if data.draw(st.booleans()):
            d[data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, segs - 1))] = 0.0
    else:
        d = data.draw(st.sampled_from([np.zeros(shape), 'up', [[None]], np.ones(shape)]))
    before = [a.copy() for a in (placed.pos, placed.vel, placed.pos_prev)]
    try:
        placed.set_directions(d)
    except ValueError:
        for a, b in zip((placed.pos, placed.vel, placed.pos_prev), before):
            assert np.array_equal(a, b)
        return
    placed.step(DEFAULT_DT)
    assert np.all(np.isfinite(placed.pos))


def _bare_rest():
    """Three straight strands of five segments standing on a 0.1 m head, head frame."""
    from hair_sim.bench import hanging
    return hanging.rest_strands(3, 5), hanging.head_model()


@pytest.mark.parametrize('model', ['anjyo', 'articulated'])
@pytest.mark.parametrize('case', ['nan', 'inf', 'far', 'flat', 'one vertex', 'no strand',
                                  'xy only', 'text', 'pair out of range', 'pair to itself',
                                  'pair negative', 'pair not a pair'])
def test_bare_strands_that_are_not_strands_are_refused_with_a_reason(model, case):
    """
    from_strands: NaN, infinite, far-flung or misshapen rests and bad pairs are ValueError.

    Before, a NaN or a 1e300 in a rest built a simulator whose first step diverged and put
    the hair back at that same rest; a 2-D array reached the kernels (a numba typing
    error); an empty one failed on a reduction with no word of the rest.
    """
    rest, head = _bare_rest()
    pairs = None
    if case == 'nan':
        rest[0, 2, 1] = np.nan
    elif case == 'inf':
        rest[1, 3, 0] = np.inf
    elif case == 'far':
        rest[2, 4, 2] = 1e300
    elif case == 'flat':
        rest = rest[0]
    elif case == 'one vertex':
        rest = rest[:, :1]
    elif case == 'no strand':
        rest = rest[:0]
    elif case == 'xy only':
        rest = rest[..., :2]
    elif case == 'text':
        rest = 'strands'
    else:
        pairs = {'pair out of range': [[0, 3]], 'pair to itself': [[1, 1]],
                 'pair negative': [[-1, 0]], 'pair not a pair': [[0, 1, 2]]}[case]
    with pytest.raises(ValueError, match='rest strands|pairs'):
        HairSimulator.from_strands(rest, head, pairs=pairs, model=model)


def test_bare_strands_that_are_strands_are_taken():
    """The same rest untouched, with a valid pair, simulates and stays finite."""
    rest, head = _bare_rest()
    sim = HairSimulator.from_strands(rest, head, pairs=[[0, 1]], model='articulated')
    sim.step(DEFAULT_DT)
    assert np.all(np.isfinite(sim.pos)) and len(sim.pairs) == 1
