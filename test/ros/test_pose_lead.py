"""
The pose clock's slew: latency that no pose needs is taken away, smoothly, and only that.

PoseLead is driven here with a simulated arrival process (deterministic, no ROS): poses at
100 Hz whose simulator times land `excess` ahead of the simulator's clock, less a delay
that varies from pose to pose, and a node that applies each slew as the node does
(HairSimulator.skip_time moves every later pose's lead down by the same amount).
"""

import numpy as np
import pytest

from hair_sim.physics.motion import HeadMotion
from hair_sim.physics.params import PhysicsParams
from hair_sim.ros import pose_lead
from hair_sim.ros.pose_lead import PoseLead


def _run(excess, jitter, seconds=6.0, seed=0):
    """Return (slews per frame, the leads as they landed, their arrival times)."""
    rng = np.random.default_rng(seed)
    motion = HeadMotion(PhysicsParams())
    motion.add(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)     # an anchor
    lead = PoseLead()
    moved = 0.0                   # how far the mapping was moved on so far
    frame, slews, landed, times = 1.0 / 60.0, [], [], []
    t_pose, t_frame = 0.0, 0.0
    while t_frame < seconds:
        t_frame += frame
        while t_pose + 0.01 <= t_frame:
            t_pose += 0.01
            delay = rng.uniform(0.0, jitter)
            landed.append(excess - delay - moved)
            times.append(t_pose)
            lead.note(motion, t_pose + delay, landed[-1])
        step = lead.slew(t_frame, frame)
        moved += step
        slews.append(step)
    return np.array(slews), np.array(landed), np.array(times)


@pytest.mark.parametrize('excess', [0.015, 0.04, 0.2])
@pytest.mark.parametrize('jitter', [0.0, 0.008])
def test_a_late_anchor_is_slewed_away_at_a_bounded_rate(excess, jitter):
    """
    Poses landing `excess` ahead, less a delay up to `jitter`, are slewed to MARGIN.

    The least lead ends at MARGIN, the slew starting no sooner than MIN_SPAN after the
    anchor and never faster than RATE.
    """
    slews, landed, times = _run(excess, jitter, seconds=2.0 + excess / pose_lead.RATE)
    frame = 1.0 / 60.0
    assert slews.min() >= 0.0
    assert slews.max() <= pose_lead.RATE * frame + 1e-12
    first = np.argmax(slews > 0) * frame
    assert first >= pose_lead.MIN_SPAN - 1e-9
    last_second = landed[times > times[-1] - pose_lead.WINDOW]
    assert abs(last_second.min() - pose_lead.MARGIN) < 1e-3, last_second.min()
    # the least punctual pose decides: nothing beyond the excess the jitter leaves
    assert slews.sum() <= excess - pose_lead.MARGIN + 1e-9


@pytest.mark.parametrize('excess', [-0.01, 0.0, pose_lead.MARGIN])
def test_poses_that_land_on_time_or_late_are_left_alone(excess):
    """A mapping that needs no buffer beyond MARGIN is never moved, nor moved back."""
    slews, _, _ = _run(excess, 0.005)
    assert slews.sum() == 0.0


def test_one_punctual_pose_among_late_ones_holds_the_slew():
    """The least lead of the window decides: one pose landing late keeps the buffer."""
    motion = HeadMotion(PhysicsParams())
    motion.add(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)
    lead = PoseLead()
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
    motion = HeadMotion(PhysicsParams())
    motion.add(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)
    lead = PoseLead()
    n = 1_000_000
    for i in range(n):
        lead.note(motion, 0.9 * i / n, 0.0 if i < n - pose_lead.MAX_POSES else 0.05)
    assert len(lead._leads) == pose_lead.MAX_POSES
    assert lead.least(0.9) == 0.05


def test_a_node_clock_that_jumps_back_forgets_the_arrivals_after_it():
    """A looping bag's clock: the arrivals from before the jump back are forgotten."""
    motion = HeadMotion(PhysicsParams())
    motion.add(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], now=0.0)
    lead = PoseLead()
    for i in range(100):
        lead.note(motion, 50.0 + 0.01 * i, 0.0)          # on time, before the jump back
    for i in range(100):
        lead.note(motion, 10.0 + 0.01 * i, 0.05)         # then poses landing 50 ms early
    assert lead.least(11.0) == pytest.approx(0.05)
    assert lead.slew(11.0, 1.0 / 60.0) == pytest.approx(pose_lead.RATE / 60.0)
