"""SimClockWatch: a ROS clock under use_sim_time that stands still, on fake clocks."""

import pytest

from hair_sim.ros.sim_clock import SimClockWatch, STILL_AFTER


def _run(watch, ticks):
    """Note (ros_ns, steady_s) pairs; return the news of each."""
    return [watch.note(ros, steady) for ros, steady in ticks]


def test_no_clock_at_all_is_said_once_after_still_after():
    watch = SimClockWatch(10.0)
    news = _run(watch, [(0, 10.0 + i) for i in range(1, 10)])
    assert news.count('stopped') == 1 and news.count('resumed') == 0
    assert news.index('stopped') == int(STILL_AFTER) - 1       # noted at 10 + STILL_AFTER
    assert watch.never_ran() and watch.still and watch.stalls == 1
    assert watch.still_for(19.0) == pytest.approx(9.0)


def test_a_clock_that_runs_is_never_said():
    watch = SimClockWatch(0.0)
    assert _run(watch, [(10 ** 9 * i, float(i)) for i in range(1, 30)]) == [None] * 29
    assert not watch.still and watch.stalls == 0 and not watch.never_ran()


def test_a_paused_clock_is_said_and_its_start_again_too():
    watch = SimClockWatch(0.0)
    ticks = [(10 ** 9 * i, float(i)) for i in range(1, 5)]          # runs 4 s
    ticks += [(4 * 10 ** 9, 4.0 + i) for i in range(1, 6)]          # paused 5 s
    ticks += [(4 * 10 ** 9 + 10 ** 8 * i, 9.0 + i) for i in range(1, 3)]
    news = _run(watch, ticks)
    assert [n for n in news if n] == ['stopped', 'resumed']
    assert news.index('stopped') == 3 + int(STILL_AFTER)
    assert not watch.still and watch.stalls == 1 and not watch.never_ran()


def test_a_clock_that_arrives_late_is_news_and_a_second_stall_counts_again():
    watch = SimClockWatch(0.0)
    news = _run(watch, [(0, 1.0), (0, 2.0), (0, 3.0), (0, 4.0), (5 * 10 ** 9, 5.0)])
    assert news[-1] == 'resumed' and news.count('stopped') == 1
    news = _run(watch, [(5 * 10 ** 9, 5.0 + i) for i in range(1, 5)])
    assert news.count('stopped') == 1 and watch.stalls == 2
    # a clock stepping back (a looping bag) is movement, not a stall
    assert watch.note(10 ** 9, 10.0) == 'resumed' and not watch.still


def test_ticks_that_come_in_a_burst_just_after_the_clock_starts_are_simulated(monkeypatch):
    """
    A node held up as the /clock starts sees its first ticks at once: none is dropped.

    Its step budget (SIM_CLOCK_TICKS_MAX) held one frame's steps at the anchor, and wall
    time had no chance to refill it: 0.3 s of a 10 Hz clock seen at once lost 0.23 s as
    an overrun (test_boundary 21 failed so in 2 of 6 runs on a loaded machine).

    The solver's wall-time share (PHYSICS_CREDIT, FRAME_SPEND_TICKS) is another limit, on
    purpose: 72 steps in one call take 20-30 ms, over one call's 20 ms on a slow machine
    (a fresh one dropped 0.0625 s so). It is lifted here, so that only the step budget
    and the overrun are measured.
    """
    import os
    from rclpy.time import Time
    from hair_sim import HairSimulator, paths
    from hair_sim.ros import node as node_module
    from hair_sim.ros.node import SIM_CLOCK_TICKS_MAX
    from helpers.ros import RunningNode
    monkeypatch.setattr(node_module, 'PHYSICS_CREDIT', 1e3)
    monkeypatch.setattr(node_module, 'FRAME_SPEND_TICKS', 1e6)
    run = RunningNode(['--params-file', os.path.join(paths.config_dir(), 'hair_sim.yaml'),
                       '-p', 'use_sim_time:=true', '-p', 'meshcat.enabled:=false'])
    try:
        node = run.node                       # not spun: the frames are driven here
        clock = node.get_clock()
        h = 1.0 / node.get_parameter('sim_rate').value
        # the kernels loaded first (a first step that loads them outruns the solver's
        # share of the wall time, and the rest of the burst is dropped for that)
        HairSimulator(node.sim.style, **node.sim.params.__dict__).step(h)
        cap = node.get_parameter('max_steps_per_frame').value
        start = 1000.0
        clock.set_ros_time_override(Time(seconds=start, clock_type=clock.clock_type))
        node._advance()                       # the anchor
        t0 = node.sim.time
        burst = 0.3                           # three ticks of 0.1 s, seen at once
        assert burst / h > 4 * cap and burst / h < SIM_CLOCK_TICKS_MAX * cap
        clock.set_ros_time_override(Time(seconds=start + burst, clock_type=clock.clock_type))
        node._advance()
        assert node.overrun_dropped == 0.0 and node.counts['overruns'] == 0
        assert node.sim.time_dropped == 0.0
        assert node.sim.time - t0 == pytest.approx(burst, abs=h + 1e-9)
    finally:
        run.close()
