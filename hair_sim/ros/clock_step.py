"""
Wake a node's executor when the system clock steps (an NTP correction, `date -s`).

The ROS 2 Jazzy wheels' rmw (librmw_fastrtps_shared_cpp) waits with pthread_cond_timedwait,
which times out on the system clock: a wait in flight when the clock steps back by 60 s
lasts 60 s longer, and a process whose executor nothing else wakes (no message, no service
call) stands still that long, timers on a steady clock or not (2026-11-30: a 100 Hz publisher
on a steady timer sent nothing from the step until the clock was put back). Waits begun
after the step time out as they should.

ClockStepWaker watches the system clock against the monotonic one from a thread, and on a
step triggers a guard condition of the node: the wait in flight returns, and the executor's
next wait times out on the clock as it now is.
"""

import threading
import time

from rclpy.exceptions import InvalidHandle

CHECK_PERIOD = 0.05      # s between looks at the two clocks
STEP_THRESHOLD = 0.02    # s the system clock may move other than the monotonic one


def _clocks_together(within, tries=5):
    """
    Return (system, monotonic) clock read within `within` s of each other, else None.

    A thread held up between the two reads (the machine busy, another thread holding the
    GIL) would see the difference as a step; such a read is tried again.
    """
    for _ in range(tries):
        before = time.monotonic()
        wall = time.time()
        after = time.monotonic()
        if after - before <= within:
            return wall, 0.5 * (before + after)
    return None


class ClockStepWaker:
    """Trigger a guard condition of `node` whenever the system clock steps; count the steps."""

    def __init__(self, node, on_step=None, period=CHECK_PERIOD, threshold=STEP_THRESHOLD):
        self.steps = 0                    # steps seen
        self._period = period
        self._threshold = threshold
        self._on_step = on_step
        self._pending = []                # steps not yet passed to on_step (executor side)
        self._lock = threading.Lock()
        self._guard = node.create_guard_condition(self._woken)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name='clock_step_waker',
                                        daemon=True)
        self._thread.start()

    def _watch(self):
        wall0, mono0 = _clocks_together(self._threshold / 4) or (None, None)
        while not self._stop.wait(self._period):
            read = _clocks_together(self._threshold / 4)
            if read is None:
                continue                  # the thread was held up between the reads
            if wall0 is None:
                wall0, mono0 = read
                continue
            step = (read[0] - wall0) - (read[1] - mono0)
            wall0, mono0 = read
            if abs(step) > self._threshold:
                with self._lock:
                    self.steps += 1
                    self._pending.append(step)
                try:
                    self._guard.trigger()
                except InvalidHandle:     # the node or its context went without stop()
                    return

    def _woken(self):
        """Executor thread: the wait that was in flight has returned; say why."""
        with self._lock:
            pending, self._pending = self._pending, []
        if self._on_step is not None:
            for step in pending:
                self._on_step(step)

    def stop(self):
        """Stop watching (the node is going)."""
        self._stop.set()
        self._thread.join(timeout=1.0)
