"""
How far ahead of the simulator's clock head poses land, and the slew of needless latency.

HeadMotion maps pose stamps onto the simulator's clock by an offset, anchored at the first
pose: that pose's simulator time is the simulator's clock when it was handled. If the
node handled it late (busy starting up: on a cold numba cache the first frames compile
kernels), every later pose lands that much ahead of the simulator's clock, and the hair
follows the head that much late for as long as the node runs. Measured with
`python -m hair_sim.bench.probe` on `make demo`: hair_mesh 39 ms behind the pose it
followed (p50 and p95) on the first run after `make clean-cache`, 6-7 ms on the next runs.

So each accepted pose's lead is noted: its simulator time (stamp - offset) minus the
simulator's clock when it arrived. When even the least punctual pose of the last WINDOW
seconds landed more than MARGIN ahead, no pose needs that much buffer, and the mapping is
moved on (HairSimulator.skip_time) by at most RATE seconds per second: the head's motion
plays at most 5 % faster while it catches up, and never jumps (a jump in the pose clock is a
jump of the head, and of the hair's roots, in one step). It is never moved back: a pose
that lands behind the simulator's clock holds the head until the next one, and HeadMotion
re-anchors past MAX_GAP.
"""

from collections import deque

WINDOW = 1.0          # s of arrivals the least lead is taken over
MIN_SPAN = 0.5        # s of arrivals needed before anything moves
MIN_POSES = 5
MAX_POSES = 4096     # kept at most (a flood of poses keeps the newest)
MARGIN = 0.002        # s a pose may land ahead of the simulator's clock, at the least
RATE = 0.05           # s the mapping moves per s, at most


class PoseLead:
    """The leads of the last WINDOW seconds of poses, and the slew they call for."""

    def __init__(self):
        self._leads = deque(maxlen=MAX_POSES)  # (arrival on the node's clock, lead + shift)
        self._shift = 0.0            # s the mapping was moved on since the anchor
        self._anchor = None          # (HeadMotion, its anchor count) the leads belong to
        self.slewed = 0.0            # s moved on in all

    def note(self, motion, arrival, lead):
        """
        Note a pose's lead (s) under `motion`'s current anchor, arrived at `arrival` (s).

        A new anchor (a first pose, a clock jump, another simulator) starts afresh: the
        leads under the old one say nothing of the new mapping. So does an arrival before
        the last one: the node's clock jumped back (a looping bag's /clock).
        """
        anchor = (motion, motion.anchors)
        if anchor != self._anchor or (self._leads and arrival < self._leads[-1][0]):
            self._leads.clear()
            self._shift = 0.0
            self._anchor = anchor
        self._leads.append((arrival, lead + self._shift))

    def least(self, now):
        """Return the least lead (s) of the poses of the last WINDOW seconds, or None."""
        while self._leads and self._leads[0][0] < now - WINDOW:
            self._leads.popleft()
        if not self._leads:
            return None
        return min(stored for _, stored in self._leads) - self._shift

    def slew(self, now, elapsed):
        """
        Return how far (s) to move the mapping on at `now`, `elapsed` s after the last call.

        Zero until MIN_SPAN seconds and MIN_POSES poses were seen under this anchor; then
        the least lead's excess over MARGIN, at most RATE * elapsed. The caller moves the
        mapping (HairSimulator.skip_time); the leads noted are counted as moved with it.
        """
        least = self.least(now)
        if least is None or len(self._leads) < MIN_POSES or \
                now - self._leads[0][0] < MIN_SPAN:
            return 0.0
        step = min(least - MARGIN, RATE * max(0.0, elapsed))
        if step <= 0.0:
            return 0.0
        self._shift += step
        self.slewed += step
        return step
