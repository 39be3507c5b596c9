"""
Under use_sim_time: whether the simulated clock (/clock) runs, watched from a steady clock.

On use_sim_time the node steps and publishes on the ROS clock, which only moves when
/clock does. With no /clock (no bag playing with --clock, a simulator not started or
gone) the node published nothing and said nothing (tried 2026-11-30: 12 s, not a message
and not a line). The node's diagnostics run on a steady clock and note the ROS time each
second here; a clock that has stood still STILL_AFTER s is said once, in the log and in
/diagnostics, and so is its start again. Meanwhile the node sends its hair as it stands
once a second, and a style loaded or edited at once.
"""

STILL_AFTER = 3.0              # s of steady time without the ROS clock moving


class SimClockWatch:
    """When the ROS clock last moved, in steady seconds; how many times it stood still."""

    def __init__(self, steady_s):
        self._ros_ns = None
        self._moved_at = steady_s
        self.still = False            # standing still (for STILL_AFTER s or more)
        self.stalls = 0               # times it came to stand still

    def note(self, ros_ns, steady_s):
        """
        Note the ROS time at steady time steady_s; return what changed.

        Returns 'stopped' when the clock has now stood still STILL_AFTER s (once a stall),
        'resumed' when it moved after that, and None otherwise.
        """
        if ros_ns != self._ros_ns:
            known = self._ros_ns is not None
            self._ros_ns = ros_ns
            if known or ros_ns != 0:      # (a time of 0 at the start is no /clock yet)
                self._moved_at = steady_s
                if self.still:
                    self.still = False
                    return 'resumed'
                return None
        if not self.still and steady_s - self._moved_at >= STILL_AFTER:
            self.still = True
            self.stalls += 1
            return 'stopped'
        return None

    def still_for(self, steady_s):
        """Return for how long (s) the ROS clock has not moved."""
        return steady_s - self._moved_at

    def never_ran(self):
        """Return whether no /clock has arrived: the ROS time is still zero."""
        return self._ros_ns == 0
