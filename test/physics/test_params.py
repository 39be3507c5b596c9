"""Parameters of any numeric kind (int, numpy scalars) act exactly as the float they equal."""

import math
import sys

import numba
import numpy as np
import pytest

from hair_sim import HairSimulator
from hair_sim.bench import hanging
from hair_sim.physics.params import PhysicsParams, RANGES

STEPS = 4


def _integer_in_range(name):
    """Return an int in the parameter's range near its default, or None if none fits."""
    lo, hi = RANGES[name]
    v = int(round(getattr(PhysicsParams(), name)))
    if lo <= v <= hi:
        return v
    v = math.ceil(lo)
    return v if v <= hi else None


INT_FIELDS = [n for n in RANGES if _integer_in_range(n) is not None]


def _compiled_signatures():
    """Return how many signatures numba has compiled or loaded for hair_sim's kernels."""
    total = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith('hair_sim') or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, numba.core.registry.CPUDispatcher):
                total += len(value.signatures)
    return total


def _run(model, **params):
    sim = HairSimulator.from_strands(hanging.rest_strands(3, 4), hanging.head_model(),
                                     model=model, **params)
    for i in range(STEPS):
        sim.set_head_pose((i + 1) / 60.0, [0.01 * i, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
        sim.set_wind([2.0, 0.0, 0.0], turbulence=0.5, seed=1)
        sim.step(1.0 / 60.0)
    return sim


@pytest.mark.parametrize('model', ['anjyo', 'articulated'])
def test_an_integer_parameter_steps_as_its_float_without_compiling_again(model):
    # (before: max_head_acceleration=300 passed the constructor and the step then raised
    # numba's TypingError; contact_friction=1 on the articulated model compiled the
    # kernels again for ints, 11 s, and so did every int for some kernel)
    assert {'max_head_acceleration', 'contact_friction', 'collision_stiffness', 'damping',
            'gravity'} <= set(INT_FIELDS)
    for name in INT_FIELDS:
        v = _integer_in_range(name)
        reference = _run(model, **{name: float(v)})
        before = _compiled_signatures()
        sim = _run(model, **{name: v})
        assert type(getattr(sim.params, name)) is float, name
        assert _compiled_signatures() == before, '%s=%r compiled kernels again' % (name, v)
        np.testing.assert_array_equal(sim.strand_positions(), reference.strand_positions(),
                                      err_msg=name)
        # and through set_params, on a simulator already running
        sim = _run(model)
        sim.set_params(**{name: v})
        assert type(getattr(sim.params, name)) is float, name


@pytest.mark.parametrize('value', [np.float32(8.5), np.float64(8.5), np.int64(8), 8,
                                   np.int32(8)])
def test_numpy_scalars_are_numbers(value):
    # (before: np.float32 and np.int64 were refused as "not a number")
    p = PhysicsParams().replaced(damping=value)
    assert p.damping == float(value) and type(p.damping) is float
    assert PhysicsParams().replaced(collisions=np.False_).collisions is False


@pytest.mark.parametrize('value', [True, np.True_, '8', None, [8.0], 10 ** 400, -10 ** 400,
                                   float('nan'), math.inf, 201])
def test_what_is_no_number_in_range_is_refused_with_its_name(value):
    with pytest.raises(ValueError, match='damping'):
        PhysicsParams().replaced(damping=value)
    with pytest.raises(ValueError, match='collisions'):
        PhysicsParams().replaced(collisions=1)
