"""
The pose clock's slew: latency no pose needs is taken away, a pose interval is buffered.

PoseLead is driven here with a simulated arrival process (deterministic, no ROS): poses
every `gap` seconds whose simulator times land `excess` ahead of the simulator's clock,
less a delay that varies from pose to pose, and a node that applies each slew as the node
does (HairSimulator.shift_pose_clock moves every later pose's lead by the same amount).
A pose's slack is its lead less the gap to the pose before: how far ahead of the
simulator's clock that pose still was when this one landed (negative: the head was held
at it that long).
"""

import numpy as np
import pytest

from hair_sim.physics.motion import HeadMotion
from hair_sim.physics.params import PhysicsParams
from hair_sim.ros import pose_lead
from hair_sim.ros.pose_lead import PoseLead

FRAME = 1.0 / 60.0


def _anchored():
    motion = HeadMotion(PhysicsParams())
    motion.add(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)     # an anchor
    return motion


def _run(excess, jitter, interpolate=True, gap=0.01, seconds=6.0, seed=0):
    """Return (slews per frame, the leads as they landed, their arrival times)."""
    rng = np.random.default_rng(seed)
    motion = _anchored()
    lead = PoseLead(interpolate)
    moved = 0.0                   # how far the mapping was moved on so far
    slews, landed, times = [], [], []
    t_pose, t_frame = 0.0, 0.0
    while t_frame < seconds:
        t_frame += FRAME
        while t_pose + gap <= t_frame:
            t_pose += gap
            delay = rng.uniform(0.0, jitter)
            landed.append(excess - delay - moved)
            times.append(t_pose)
            lead.note(motion, t_pose + delay, landed[-1], gap)
        step = lead.slew(t_frame, FRAME)
        moved += step
        slews.append(step)
    return np.array(slews), np.array(landed), np.array(times)


@pytest.mark.parametrize('excess', [0.0, 0.015, 0.04, 0.2])
@pytest.mark.parametrize('jitter', [0.0, 0.008])
@pytest.mark.parametrize('gap', [0.01, 1.0 / 30.0])
def test_poses_are_followed_one_interval_late_whenever_they_land(excess, jitter, gap):
    """
    Poses landing on time (a live tracker) or early (a late anchor) end a pose interval ahead.

    The head is then interpolated between poses for all but HELD_SHARE of them (their
    slack is not negative), and no pose keeps more than MARGIN of slack (no latency beyond
    that). The slew starts no sooner than MIN_SPAN after the anchor, never faster than RATE.
    """
    seconds = 2.0 + (abs(excess - gap) + jitter) / pose_lead.RATE
    slews, landed, times = _run(excess, jitter, gap=gap, seconds=seconds)
    assert np.abs(slews).max() <= pose_lead.RATE * FRAME + 1e-12
    assert np.argmax(slews != 0.0) * FRAME >= pose_lead.MIN_SPAN - 1e-9
    slack = landed[times > times[-1] - pose_lead.WINDOW] - gap
    assert np.quantile(slack, pose_lead.HELD_SHARE) > -1e-3, np.sort(slack)[:5]
    assert slack.min() < pose_lead.MARGIN + 1e-3, slack.min()


@pytest.mark.parametrize('excess', [0.015, 0.04, 0.2])
@pytest.mark.parametrize('jitter', [0.0, 0.008])
def test_without_interpolation_a_late_anchor_is_slewed_away_at_a_bounded_rate(excess, jitter):
    """
    Without interpolation, poses landing `excess` ahead (less up to `jitter`) end MARGIN ahead.

    The least lead ends at MARGIN, the slew starting no sooner than MIN_SPAN after the
    anchor and never faster than RATE.
    """
    slews, landed, times = _run(excess, jitter, interpolate=False,
                                seconds=2.0 + excess / pose_lead.RATE)
    assert slews.min() >= 0.0
    assert slews.max() <= pose_lead.RATE * FRAME + 1e-12
    first = np.argmax(slews > 0) * FRAME
    assert first >= pose_lead.MIN_SPAN - 1e-9
    last_second = landed[times > times[-1] - pose_lead.WINDOW]
    assert abs(last_second.min() - pose_lead.MARGIN) < 1e-3, last_second.min()
    # the least punctual pose decides: nothing beyond the excess the jitter leaves
    assert slews.sum() <= excess - pose_lead.MARGIN + 1e-9


@pytest.mark.parametrize('excess', [-0.01, 0.0, pose_lead.MARGIN])
def test_without_interpolation_poses_that_land_on_time_or_late_are_left_alone(excess):
    """Without interpolation, a mapping that needs no buffer beyond MARGIN is never moved."""
    slews, _, _ = _run(excess, 0.005, interpolate=False)
    assert slews.sum() == 0.0


def test_a_slow_tracker_is_buffered_no_more_than_max_buffer():
    """A 5 Hz tracker's poses land at most MAX_BUFFER ahead: the head is held the rest."""
    slews, landed, times = _run(0.0, 0.0, gap=0.2, seconds=6.0)
    assert slews.min() < 0.0
    last_second = landed[times > times[-1] - pose_lead.WINDOW]
    assert pose_lead.MAX_BUFFER - 1e-3 < last_second.min() <= pose_lead.MAX_BUFFER + 1e-9


def test_a_tracker_that_pauses_is_not_buffered_for_its_pause():
    """
    A pause (the face out of view for 3 s) is no pose interval: nothing is moved back.

    A 15 Hz tracker's poses, on time with a pose interval of slack; then none for 3 s; then
    on time again (so few poses a window that the least slack decides).
    """
    motion = _anchored()
    lead = PoseLead()
    slews = []
    gap = 1.0 / 15.0
    for i in range(90):
        t = gap * i + (3.0 if i >= 45 else 0.0)
        lead.note(motion, t, gap + 0.001, 3.0 + gap if i == 45 else gap)
        slews.append(lead.slew(t, gap))
    assert min(slews) == 0.0 and max(slews) == 0.0


@pytest.mark.parametrize('stragglers', [1, 5, 6])
def test_stragglers_hold_the_slew_when_more_than_held_share_of_the_poses(stragglers):
    """
    With interpolate, the HELD_SHARE quantile of the slacks decides, not the least.

    100 poses a window, a pose interval and 50 ms to spare, but `stragglers` of them land
    with none: up to 5 (HELD_SHARE) leave the slew on; 6 hold it.
    """
    motion = _anchored()
    lead = PoseLead()
    for i in range(100):
        straggler = i % 16 == 3 and i // 16 < stragglers
        lead.note(motion, 0.01 * i, 0.01 + (0.0 if straggler else 0.05), 0.01)
    step = lead.slew(1.0, 1.0 / 60.0)
    assert step == (0.0 if stragglers > 5 else pytest.approx(pose_lead.RATE / 60.0))


def test_one_punctual_pose_among_late_ones_holds_the_slew_without_interpolation():
    """Without interpolation the least lead decides: one pose landing late keeps the buffer."""
    motion = _anchored()
    lead = PoseLead(interpolate=False)
    for i in range(100):
        lead.note(motion, 0.01 * i, 0.0 if i == 60 else 0.05)
    assert lead.slew(1.0, 1.0 / 60.0) == 0.0
    assert lead.least(1.0) == 0.0
    # a window later that pose has left it
    for i in range(100, 200):
        lead.note(motion, 0.01 * i, 0.05)
    assert lead.slew(2.0, 1.0 / 60.0) == pytest.approx(pose_lead.RATE / 60.0)


def test_a_new_anchor_forgets_the_leads_of_the_old():
    """After a clock jump (HeadMotion re-anchors) the old leads no longer count."""
    motion = HeadMotion(PhysicsParams())
    motion.add(100.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)
    lead = PoseLead()
    for i in range(100):
        lead.note(motion, 0.01 * i, 0.05)
    # the tracker restarts: its clock jumps back by a minute
    assert motion.add(40.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=1.0) == 'clock_jump'
    lead.note(motion, 1.0, 0.0)
    assert lead.least(1.0) == 0.0
    assert lead.slew(1.0, 1.0 / 60.0) == 0.0       # one pose: no evidence yet


def test_a_flood_of_poses_keeps_the_memory_bounded():
    """A million poses within one window: the newest MAX_POSES are kept, and decide."""
    motion = _anchored()
    lead = PoseLead()
    n = 1_000_000
    for i in range(n):
        lead.note(motion, 0.9 * i / n, 0.0 if i < n - pose_lead.MAX_POSES else 0.05)
    assert len(lead._leads) == pose_lead.MAX_POSES
    assert lead.least(0.9) == 0.05


def test_a_node_clock_that_jumps_back_forgets_the_arrivals_after_it():
    """A looping bag's clock: the arrivals from before the jump back are forgotten."""
    motion = _anchored()
    lead = PoseLead()
    for i in range(100):
        lead.note(motion, 50.0 + 0.01 * i, 0.0)          # on time, before the jump back
    for i in range(100):
        lead.note(motion, 10.0 + 0.01 * i, 0.05)         # then poses landing 50 ms early
    assert lead.least(11.0) == pytest.approx(0.05)
    assert lead.slew(11.0, 1.0 / 60.0) == pytest.approx(pose_lead.RATE / 60.0)
