"""
HairSimulator.max_step_work: a step cut to the segment-substeps it may take.

The articulated model's substeps grow with how fast its tips whip; in the strongest wind
the node accepts, a 1/60 s step took up to 0.4 s of wall. With max_step_work a step
simulates the share of its time that fits and drops the rest, as a driver that falls
behind does, and so does a step taken again (a strand outran its substeps). Checked here:
the work bound holds, retries included, no input time is lost or invented, the
hair still follows the head's newest pose, nothing diverges or enters a sphere, and a
bound that never binds changes nothing, bit for bit.
"""

import numpy as np
import pytest

from hair_sim.bench.stress import _penetration
from hair_sim.physics.motion import quat_to_matrix
from hair_sim.physics.simulator import HairSimulator

DT = 1.0 / 60.0


def yaw(angle):
    return (0.0, 0.0, np.sin(angle / 2.0), np.cos(angle / 2.0))


def gale_run(style, cap, seconds=1.5, model='articulated'):
    """Run a 40 m/s gale with a turning head; return the simulator and per-step records."""
    sim = HairSimulator(style, model=model)
    sim.max_step_work = cap
    t = 0.0
    sim.set_head_pose(t, (0.0, 0.0, 0.0), yaw(0.0))
    sim.step(DT)
    sim.set_wind([40.0, 5.0, 0.0], turbulence=1.0, seed=3)
    records = []
    for _ in range(int(round(seconds / DT))):
        t += DT
        sim.set_head_pose(t, (0.0, 0.0, 0.0), yaw(0.8 * np.sin(2 * np.pi * 0.7 * t)))
        before = (sim.counters['segment_updates'], sim.counters['retried_steps'], sim.time)
        sim.step(DT)
        records.append((sim.counters['segment_updates'] - before[0],
                        sim.counters['retried_steps'] - before[1], sim.time - before[2],
                        _penetration(sim)))
        assert np.isfinite(sim.pos).all()
    return sim, t, records


@pytest.mark.parametrize('cap', [5000, 20000])
def test_a_bounded_step_keeps_its_bound_and_the_input_clock(long_style, cap):
    sim, t, records = gale_run(long_style, cap)
    work = np.array([r[0] for r in records])
    retried = np.array([r[1] for r in records])
    simulated = np.array([r[2] for r in records])
    n_strands, n_seg = sim.pos.shape[0], sim.pos.shape[1] - 1
    # the counts are whole substeps of the strand that needs the most (every strand takes
    # it: springs join them), so a cut step may be up to one of them over the bound
    slack = n_strands * n_seg
    assert work[retried == 0].max() <= cap + slack, work.max()
    # A step taken again is cut to the bound too: its first try (within the bound) plus a
    # retry within it. The gale's first step, from rest, outran its one substep and was
    # taken again at the count its end needed, 114 264 segment-substeps at either bound
    # (23 and 5.7 times it), until retries were cut as well.
    assert retried.sum() >= 1
    assert work[retried > 0].max() <= 2 * (cap + slack), work[retried > 0]
    assert sim.counters['shortened_steps'] > len(records) // 2       # the gale needs more
    # a step counts once, whether it was cut, its retry was, or both
    assert sim.counters['shortened_steps'] == int((simulated < DT - 1e-12).sum())
    assert simulated.min() < 0.5 * DT
    # no input time lost or invented: simulated plus dropped is what was stepped
    assert abs(sim.time + sim.time_dropped - (t + DT)) < 1e-9, (sim.time, sim.time_dropped, t)
    assert sim.counters['diverged'] == 0
    assert max(r[3] for r in records) <= 1e-3
    # the hair follows the newest pose, not one the dropped time left behind: the roots
    # sit where the head's pose of the last input puts them
    R, p = sim.head_pose
    assert np.abs(R - quat_to_matrix(yaw(0.8 * np.sin(2 * np.pi * 0.7 * t)))).max() < 1e-6
    assert np.abs(sim.pos[:, 0] - (sim.rest[:, 0] @ R.T + p)).max() < 1e-9


def test_a_bound_that_never_binds_changes_nothing(long_style):
    free, _, _ = gale_run(long_style, None, seconds=0.5)
    roomy, _, _ = gale_run(long_style, 10 ** 9, seconds=0.5)
    assert roomy.counters['shortened_steps'] == 0
    assert np.array_equal(free.pos, roomy.pos)
    assert free.time == roomy.time and roomy.time_dropped == 0.0


def test_the_thesis_models_substeps_are_set_by_the_step_not_the_swing(long_style):
    """
    Take a fixed number of substeps, whatever the swing.

    MAX_TURN bounds a turn, so the cost does not grow with it: with collisions and
    springs a 1/60 s step is two substeps of 1/120 s (CONTACT_SUBSTEP) through the whole
    gale, and a bound under one step's work cuts every step to one of them, the rest
    counted.
    """
    sim, t, records = gale_run(long_style, None, seconds=0.5, model='anjyo')
    n_strands, n_seg = sim.pos.shape[0], sim.pos.shape[1] - 1
    assert {r[0] for r in records} == {2 * n_strands * n_seg}
    assert sim.counters['substeps'] == 2 * sim.counters['steps']
    assert sim.counters['shortened_steps'] == 0 and sim.time_dropped == 0.0
    cut, t, records = gale_run(long_style, 1, seconds=0.5, model='anjyo')
    assert all(abs(r[2] - DT / 2) < 1e-12 for r in records)
    assert cut.counters['shortened_steps'] == cut.counters['steps']
    assert abs(cut.time + cut.time_dropped - (t + DT)) < 1e-9
    assert cut.counters['diverged'] == 0 and max(r[3] for r in records) <= 1e-3


@pytest.mark.parametrize('model', ['anjyo', 'articulated'])
def test_time_a_driver_drops_is_counted_and_the_pose_clock_moves_on(long_style, model):
    """
    drop_time and skip_time both move the pose clock on; only drop_time counts the time.

    The node dropped the steps its share of the wall time did not pay for through
    skip_time, so time_dropped_s left them out: an articulated node on a 3x /clock fell
    1.7 s behind it with time_dropped_s at 0.14 and no other count of it.
    """
    runs = {}
    for how in ('drop_time', 'skip_time', None):
        sim = HairSimulator(long_style, model=model)
        t = 0.0
        sim.set_head_pose(t, (0.0, 0.0, 0.0), yaw(0.0))
        for k in range(30):
            t += DT
            sim.set_head_pose(t, (0.0, 0.0, 0.0), yaw(0.6 * np.sin(2 * np.pi * t)))
            if how is not None and k == 10:
                getattr(sim, how)(5 * DT)             # five steps not taken
                t += 5 * DT
                sim.set_head_pose(t, (0.0, 0.0, 0.0), yaw(0.6 * np.sin(2 * np.pi * t)))
            sim.step(DT)
        runs[how] = (sim, t)
    dropped, _ = runs['drop_time']
    assert dropped.time_dropped == pytest.approx(5 * DT, abs=1e-12)
    assert runs['skip_time'][0].time_dropped == 0.0 and runs[None][0].time_dropped == 0.0
    # either way the hair follows the newest pose, stamped 5 steps past its own time
    for how in ('drop_time', 'skip_time'):
        sim, t = runs[how]
        assert sim.time == pytest.approx(30 * DT, abs=1e-9)
        assert sim.stamp_at() == pytest.approx(t, abs=1e-9)
        R, p = sim.head_pose
        assert np.abs(R - quat_to_matrix(yaw(0.6 * np.sin(2 * np.pi * t)))).max() < 1e-9
    assert np.array_equal(dropped.pos, runs['skip_time'][0].pos)


@pytest.mark.parametrize('seconds', [float('nan'), float('inf'), -0.1, '0.1', True, None])
@pytest.mark.parametrize('how', ['drop_time', 'skip_time'])
def test_a_span_of_time_that_is_no_span_is_refused_and_changes_nothing(long_style, how,
                                                                       seconds):
    sim = HairSimulator(long_style)
    sim.set_head_pose(0.0, (0.0, 0.0, 0.0), yaw(0.0))
    sim.step(DT)
    before = (sim.stamp_at(), sim.time_dropped)
    with pytest.raises(ValueError, match='seconds'):
        getattr(sim, how)(seconds)
    assert (sim.stamp_at(), sim.time_dropped) == before
