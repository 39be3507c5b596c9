"""
The probe's longest gap is the longest time in its window with no message, edges included.

A probe started just before a gale's onset reported 53-68 ms where the node had stopped
publishing for 222-326 ms: the stall began as the window opened, and gaps were taken only
between the window's arrivals, so its first message, the one after the stall, hid it.

Its rate of accepted poses is timed by when the node's diagnostics arrive: timed by their
stamps, a node on use_sim_time under a looping --clock gave 7.7e11 poses a second.
"""

import pytest

from hair_sim.bench.probe import Probe


class _NoNode:
    """A node that subscribes to nothing: the arrivals are written by the test."""

    def create_subscription(self, *args, **kwargs):
        return None


def _report(arrivals, window):
    probe = Probe(_NoNode(), ['/'], ['hair_state'])
    probe.window = window
    probe.arrivals[('/', 'hair_state')] = [(t, t, None, 100) for t in arrivals]
    return probe.report(['/'], window[1] - window[0])['/']['hair_state']


def _stream(start, end, period=1.0 / 30.0):
    times, t = [], start
    while t < end:
        times.append(t)
        t += period
    return times


@pytest.mark.parametrize('stall', [(0.0, 0.25), (0.9, 1.15), (1.75, 2.0)],
                         ids=['as the window opens', 'inside it', 'as it closes'])
def test_a_stall_anywhere_in_the_window_is_its_longest_gap(stall):
    start, end = 100.0, 102.0
    a, b = start + stall[0], start + stall[1]
    got = _report(_stream(start + 0.01, a) + _stream(b, end - 0.001), (start, end))
    # (the stream resumes at b; it last arrived within a period before a, or a is the edge)
    assert 250.0 <= got['gap_ms_max'] <= 250.0 + 1e3 / 30.0 + 1.0, got


def test_a_steady_stream_has_no_gap_longer_than_its_period_and_an_edge():
    start, end = 100.0, 102.0
    got = _report(_stream(start + 0.02, end), (start, end))
    assert got['gap_ms_max'] <= 1e3 / 30.0 + 1e-6, got
    assert got['messages'] == len(_stream(start + 0.02, end))


def test_a_window_with_no_message_is_one_gap():
    got = _report([], (5.0, 7.5))
    assert got['gap_ms_max'] == pytest.approx(2500.0)


def test_accepted_poses_are_timed_by_arrival_not_by_a_simulated_clock(monkeypatch):
    """A node on use_sim_time (a bag's --clock looping back 60 s) stamps its diagnostics."""
    from types import SimpleNamespace

    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from hair_sim.bench import probe as probe_module
    now = [50.0]
    monkeypatch.setattr(probe_module, 'time', SimpleNamespace(monotonic=lambda: now[0]))
    probe = Probe(_NoNode(), ['/'], ['hair_state'])
    probe.recording = True
    probe.poses['/'] = [50.0 + i / 60.0 for i in range(601)]      # 60 Hz sent for 10 s
    sim = 1000.0
    for i in range(11):                                            # one a second, 60 each
        now[0], sim = 50.0 + i, (sim + 1.0 if i != 5 else sim - 60.0)
        msg = DiagnosticArray()
        msg.header.stamp.sec = int(sim)
        msg.status = [DiagnosticStatus(name='hair_sim: /hair_sim', values=[
            KeyValue(key='pose_accepted', value=str(60 * i))])]
        probe._on_diagnostics(msg)
    probe.window = (50.0, 60.0)
    got = probe.report(['/'], 10.0)['/']
    assert got['poses_accepted_hz'] == pytest.approx(60.0)
    assert got['poses_accepted_share'] == pytest.approx(1.0)
