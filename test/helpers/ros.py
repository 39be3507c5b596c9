"""Helpers for tests that spin rclpy executors."""

import time


def spin_until(executor, predicate, timeout_s):
    """Spin `executor` until `predicate()` is true or `timeout_s` passes; return predicate()."""
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return predicate()
