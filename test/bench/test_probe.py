"""
The probe's longest gap is the longest time in its window with no message, edges included.

A probe started just before a gale's onset reported 53-68 ms where the node had stopped
publishing for 222-326 ms: the stall began as the window opened, and gaps were taken only
between the window's arrivals, so its first message, the one after the stall, hid it.
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
