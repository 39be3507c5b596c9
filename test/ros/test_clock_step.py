"""ClockStepWaker: a step of the system clock wakes the executor and is reported, once."""

import threading
import time

import pytest

from hair_sim.ros import clock_step


class SteppableClocks:
    """time.time() as the monotonic clock plus an offset a test steps; a slow read, on ask."""

    def __init__(self):
        self.offset = 0.0
        self.slow_reads = 0               # reads of the system clock held up 30 ms

    def time(self):
        now = time.monotonic() + self.offset
        if self.slow_reads:                 # the thread held up after reading the clock
            self.slow_reads -= 1
            time.sleep(0.03)
        return now

    def monotonic(self):
        return time.monotonic()


def node_on_fake_clocks(monkeypatch, name):
    """Return (context, node, clocks): a node in its own context, clock_step on fake clocks."""
    import rclpy
    from rclpy.context import Context
    clocks = SteppableClocks()
    monkeypatch.setattr(clock_step, 'time', clocks)
    context = Context()
    rclpy.init(context=context)
    return context, rclpy.create_node(name, context=context), clocks


@pytest.fixture
def spun_node(monkeypatch):
    """Yield (node, clocks) with the node spun on a thread and clock_step on fake clocks."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    context, node, clocks = node_on_fake_clocks(monkeypatch, 'clock_step_test')
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield node, clocks
    finally:
        executor.shutdown(timeout_sec=5.0)
        thread.join(timeout=5.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize('step', [-60.0, -0.5, 0.5, 3600.0])
def test_a_step_is_passed_to_the_executor_once_with_its_size(spun_node, step):
    """Check that on_step runs on the executor's thread, once, with the step's size."""
    node, clocks = spun_node
    seen = []
    waker = clock_step.ClockStepWaker(node, on_step=lambda s: seen.append(
        (s, threading.current_thread().name)))
    try:
        time.sleep(0.3)
        assert seen == []
        clocks.offset += step
        deadline = time.monotonic() + 2.0
        while not seen and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.3)
    finally:
        waker.stop()
    assert len(seen) == 1 and waker.steps == 1, seen
    assert abs(seen[0][0] - step) < 0.01
    assert seen[0][1] != 'clock_step_waker'            # the executor's thread, not the watcher's


def test_a_read_held_up_between_the_two_clocks_is_no_step(spun_node):
    """Check that a read held up 30 ms (a busy machine) is taken again, not reported."""
    node, clocks = spun_node
    seen = []
    waker = clock_step.ClockStepWaker(node, on_step=seen.append)
    try:
        for _ in range(5):
            clocks.slow_reads = 1
            time.sleep(0.2)
        clocks.slow_reads = 50                          # every try held up: no judgement
        time.sleep(0.5)
        clocks.slow_reads = 0
        time.sleep(0.2)
    finally:
        waker.stop()
    assert seen == [] and waker.steps == 0


def test_a_node_destroyed_without_stop_ends_the_watch_quietly(monkeypatch):
    """Check that a step after the node (and its context) went ends the thread, no raise."""
    import rclpy
    context, node, clocks = node_on_fake_clocks(monkeypatch, 'clock_step_gone')
    waker = clock_step.ClockStepWaker(node)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    errors = []
    monkeypatch.setattr(threading, 'excepthook', errors.append)
    clocks.offset -= 60.0
    waker._thread.join(timeout=2.0)
    assert not waker._thread.is_alive() and errors == [] and waker.steps == 1
