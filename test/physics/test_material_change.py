"""
A change of the material while the hair moves (set_params), articulated model.

The joints' stiffness goes from the old material's to the new over MATERIAL_BLEND_S, the
preload torques that hold the style taking their new values at once: nothing jumps at
the change, the hair is not flung, and the new material is exactly in place at the end.
"""

import numpy as np
import pytest

from hair_sim import HairSimulator, load_hairstyle, paths
from hair_sim.bench.scenarios import violent
from hair_sim.physics.solvers.articulated import MATERIAL_BLEND_S

DT = 1.0 / 60.0


@pytest.fixture(scope='module')
def short_style():
    """Load thesis_short."""
    return load_hairstyle(paths.shipped_style('thesis_short'))


def _violent_until(sim, t_end, t=0.0):
    """Drive sim with the violent motion from t to t_end (s); return the time reached."""
    while t < t_end - 1e-9:
        t += DT
        sim.set_head_pose(t, *violent(t))
        sim.step(DT)
    return t


@pytest.mark.parametrize('change', [{'root_stiffness_scale': 1e4},
                                    {'root_stiffness_scale': 1e9},
                                    {'stiffness_scale': 100.0},
                                    {'youngs_modulus': 2e10},
                                    {'shape_stiffness': 1.0}])
@pytest.mark.parametrize('t_change', [0.5, 1.3])
def test_stiffening_a_swinging_strand_neither_diverges_nor_flings_it(short_style, change,
                                                                     t_change):
    """
    Much stiffer joints, set in the middle of violent motion, the motion going on.

    Applied at once, the stiffened joints, held away from their rests by the motion, got
    the energy of their new stiffness: raising root_stiffness_scale to 1e4 or more
    diverged the step (the hair was put back at rest) in every such run on e4c5c72. Now
    nothing diverges, no step is retried, and no vertex moves twice as fast as the same
    motion makes it with either material throughout.
    """
    peaks = []
    for before, after in (({}, {}), (change, change), ({}, change)):
        sim = HairSimulator(short_style, model='articulated', **before)
        t = _violent_until(sim, t_change)
        if after != before:
            sim.set_params(**after)
        peak = 0.0
        while t < 2.5 - 1e-9:
            t += DT
            sim.set_head_pose(t, *violent(min(t, 2.0)))
            sim.step(DT)
            peak = max(peak, float(np.abs(sim.vel).max()))
        peaks.append(peak)
    assert sim.counters['diverged'] == 0
    assert sim.counters['retried_steps'] == 0
    assert peaks[2] <= 2.0 * max(peaks[:2]), peaks


def test_the_change_takes_effect_smoothly_and_exactly(short_style):
    """
    The step after the change is the step without it; after MATERIAL_BLEND_S, the new one.

    The joints' stiffness then equals a simulator's built with the new parameters, as
    do the offsets, bit for bit, and in between the stiffness lies between the two.
    """
    change = {'root_stiffness_scale': 1e6}
    sims = [HairSimulator(short_style, model='articulated') for _ in range(2)]
    fresh = HairSimulator(short_style, model='articulated', **change)
    for sim in sims:
        _violent_until(sim, 0.5)
    sims[1].set_params(**change)
    assert sims[1].solver.blending
    t = 0.5 + DT
    for sim in sims:
        sim.set_head_pose(t, *violent(t))
        sim.step(DT)
    # (the same to rounding: the preload torque over the old stiffness is the old offset)
    np.testing.assert_allclose(sims[1].pos, sims[0].pos, rtol=0.0, atol=1e-12)
    k_old = sims[0].solver.k
    k_new = fresh.solver.k
    steps = 1
    while sims[1].solver.blending:
        k = sims[1].solver.k
        assert np.all(k >= np.minimum(k_old, k_new) * (1 - 1e-12))
        assert np.all(k <= np.maximum(k_old, k_new) * (1 + 1e-12))
        t += DT
        sims[1].set_head_pose(t, *violent(t))
        sims[1].step(DT)
        steps += 1
    assert steps == round(MATERIAL_BLEND_S / DT)
    np.testing.assert_array_equal(sims[1].solver.k, k_new)
    np.testing.assert_array_equal(sims[1].solver.offset, fresh.solver.offset)


@pytest.mark.parametrize('change', [{'root_stiffness_scale': 1e6},
                                    {'stiffness_scale': 20.0},
                                    {'hair_density': 3000.0},
                                    {'shape_stiffness': 1.0}])
def test_hair_at_rest_stays_put_through_a_change_and_sleeps_again(short_style, change):
    """
    The modeled pose is the equilibrium of the old material and of the new (sag-free).

    It stays one throughout the change: the new preload torques, which hold it under the
    new load, are in place at once, whatever the stiffness on the way. The hair, woken by
    the change, does not move by a tenth of a millimetre and falls asleep again once the
    change is done.
    """
    sim = HairSimulator(short_style, model='articulated')
    while not sim.sleeping:
        sim.step(DT)
    before = sim.pos.copy()
    sim.set_params(**change)
    moved = 0.0
    for i in range(int(3.0 / DT)):
        sim.step(DT)
        moved = max(moved, float(np.abs(sim.pos - before).max()))
        if sim.sleeping:
            break
    assert sim.sleeping
    assert (i + 1) * DT >= MATERIAL_BLEND_S         # not asleep before the change was done
    assert moved < 1e-4, moved
