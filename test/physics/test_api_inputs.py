"""
What a careless caller hands HairSimulator's inputs: refused whole, or taken as numbers.

numpy takes more than numbers: it drops the imaginary part of a complex value (a warning
only), reads the strings '1' and '0.5', and cuts the index 1.5 to 1. Before, a bad seed
raised after set_wind had set the new velocity, and an infinite one an OverflowError.
"""

import math

import numpy as np
import pytest

from hair_sim import DEFAULT_DT, HairSimulator
from hair_sim.bench import hanging
from hair_sim.physics.wind import Wind

# ints past a float's range (named so in test ids): float() raises OverflowError
HUGE = pytest.param(10 ** 400, id='10**400')
HUGE_NEGATIVE = pytest.param(-10 ** 400, id='-10**400')
NOT_NUMBERS = [None, 'x', '0.5', b'1', True, np.bool_(True), 1 + 2j, object(), {'a': 1}]
NOT_VECTORS = [None, 'xyz', ['1', '2', '3'], [1, 2], [1, 2, 3, 4, 5], [[1, 2], [3]],
               np.array([1 + 1j, 2, 3]), [1, None, 3], [True, False, True],
               np.array(['1', '2', '3'])]


@pytest.fixture(params=['anjyo', 'articulated'])
def moving(request):
    """Three strands on the hanging scene's head, swinging in a gust, 0.1 s in."""
    sim = HairSimulator.from_strands(hanging.rest_strands(3, 5), hanging.head_model(),
                                     model=request.param)
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    sim.set_wind([2.0, 0.0, 0.0], turbulence=0.3, seed=4)
    for _ in range(6):
        sim.step(1.0 / 60.0)
    return sim


def _state(sim):
    return (sim.time, sim.counters['steps'], sim.pos.copy(), sim.vel.copy(),
            sim.wind.velocity.copy(), sim.wind.turbulence, sim.wind.seed,
            sim.wind.amplitude, len(sim.motion.samples), sim.motion.offset)


def _assert_unchanged(before, sim):
    for a, b in zip(before, _state(sim)):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b


@pytest.mark.parametrize('bad', NOT_VECTORS + [[0, math.nan, 0], [math.inf, 0, 0]])
def test_a_wind_that_is_no_velocity_is_refused_whole(moving, bad):
    before = _state(moving)
    with pytest.raises(ValueError, match='wind'):
        moving.set_wind(bad, turbulence=0.9, seed=11)
    _assert_unchanged(before, moving)


@pytest.mark.parametrize('field', ['turbulence', 'seed'])
@pytest.mark.parametrize('bad', NOT_NUMBERS + [math.inf, math.nan, 1.5, [3], HUGE])
def test_a_turbulence_or_seed_that_is_no_number_is_refused_whole(moving, field, bad):
    """
    Refused, and nothing set (before, a bad seed raised after the velocity was set).

    A turbulence of 10 ** 400 raised OverflowError (a seed that size is a whole number).
    """
    if field == 'seed' and type(bad) is int and bad > 2 ** 64:
        pytest.skip('10 ** 400 is a seed (taken modulo 2 ** 32)')
    if field == 'turbulence' and isinstance(bad, float) and math.isfinite(bad):
        pytest.skip('1.5 is a turbulence (clamped to 1)')
    before = _state(moving)
    with pytest.raises(ValueError, match=field + '|wind'):
        moving.set_wind([0.0, 5.0, 0.0], **{'turbulence': 0.2, 'seed': 3, field: bad})
    _assert_unchanged(before, moving)
    wind = Wind()
    wind.set([1.0, 0.0, 0.0], 0.5, 9)
    kept = (wind.velocity.copy(), wind.turbulence, wind.seed)
    with pytest.raises(ValueError):
        wind.set([0.0, 5.0, 0.0], **{'turbulence': 0.2, 'seed': 3, field: bad})
    assert (wind.velocity.tolist(), wind.turbulence, wind.seed) == \
        (kept[0].tolist(), kept[1], kept[2])


@pytest.mark.parametrize('seed', [0, 7, np.uint32(2 ** 32 - 1), np.int64(-1), 2 ** 70])
def test_whole_numbers_of_any_kind_are_seeds(moving, seed):
    assert moving.set_wind([1.0, 0.0, 0.0], turbulence=0.5, seed=seed) == 'ok'
    assert moving.wind.seed == int(seed) & 0xFFFFFFFF
    moving.step(DEFAULT_DT)
    assert np.all(np.isfinite(moving.pos))


@pytest.mark.parametrize('where', ['stamp', 'position', 'quaternion'])
@pytest.mark.parametrize('bad', NOT_NUMBERS + NOT_VECTORS + [HUGE, HUGE_NEGATIVE])
def test_a_pose_that_is_not_numbers_is_invalid(moving, where, bad):
    """Counted invalid and ignored (a stamp of 10 ** 400 s raised OverflowError)."""
    before = _state(moving)
    pose = {'stamp': moving.time + 0.01, 'position': [0.0, 0.0, 0.01],
            'quaternion': [0.0, 0.0, 0.0, 1.0]}
    pose[where] = bad
    invalid = moving.motion.counts['invalid']
    assert moving.set_head_pose(pose['stamp'], pose['position'], pose['quaternion']) \
        == 'invalid'
    assert moving.motion.counts['invalid'] == invalid + 1
    _assert_unchanged(before, moving)


@pytest.mark.parametrize('bad', [np.full((3, 5, 3), 1 + 0j), np.full((3, 5, 3), '1'),
                                 np.full((3, 5, 3), True)])
def test_directions_that_are_not_real_numbers_are_refused(moving, bad):
    before = _state(moving)
    with pytest.raises(ValueError, match='directions must be real numbers'):
        moving.set_directions(bad)
    _assert_unchanged(before, moving)


@pytest.mark.parametrize('pairs', [[[0, 1.5]], [[0.0, 2.7]], [['0', '1']], [[0, 1 + 0j]],
                                   [[0, None]]])
def test_pairs_that_are_not_whole_numbers_are_refused(pairs):
    """Refused (before, [0, 1.5] joined strands 0 and 1, and [0, 2.7] strands 0 and 2)."""
    with pytest.raises(ValueError, match='pairs'):
        HairSimulator.from_strands(hanging.rest_strands(3, 5), hanging.head_model(),
                                   pairs=pairs)


def test_pairs_of_whole_floats_and_rests_of_integers_are_taken():
    rest = np.round(hanging.rest_strands(3, 5) * 1000).astype(np.int64)   # mm, as ints
    sim = HairSimulator.from_strands(rest / 1000, hanging.head_model(),
                                     pairs=np.array([[0.0, 1.0], [1.0, 2.0]]))
    np.testing.assert_array_equal(sim.pairs, [[0, 1], [1, 2]])
    with pytest.raises(ValueError, match='rest strands must be real numbers'):
        HairSimulator.from_strands(rest.astype(complex), hanging.head_model())


@pytest.mark.parametrize('call', ['step', 'turbulence', 'param'])
def test_a_refusal_quotes_a_long_value_cut_short(moving, call):
    """A megabyte string is named in 80 characters, cut with '...', not copied whole."""
    bad = 'x' * 2 ** 20
    with pytest.raises(ValueError) as refused:
        if call == 'step':
            moving.step(bad)
        elif call == 'turbulence':
            moving.set_wind([1.0, 0.0, 0.0], turbulence=bad)
        else:
            moving.set_params(damping=bad)
    message = str(refused.value)
    assert message.endswith("xxx...") and len(message) < 140, message[:200]
