"""
How far ahead of the simulator's clock head poses land, and the slew that keeps it right.

HeadMotion maps pose stamps onto the simulator's clock by an offset, anchored at the first
pose: that pose's simulator time is the simulator's clock when it was handled. Two things
go wrong with that anchor, and the mapping is slewed (moved by at most RATE seconds per
second, so the head's motion plays at most 5 % faster or slower, and never jumps: a jump
in the pose clock is a jump of the head, and of the hair's roots, in one step) to right
them.

- **Latency no pose needs.** If the node handled the first pose late (busy starting up:
  on a cold numba cache the first frames compile kernels), every later pose lands that
  much ahead of the simulator's clock, and the hair follows the head that much late for as
  long as the node runs: `make demo` right after `make clean-cache` held hair_mesh 39 ms
  behind the pose it followed (p50 and p95, `python -m hair_sim.bench.probe`), 6-7 ms on
  the next runs. When even the least punctual pose of the last WINDOW seconds (with
  `interpolate`: all but HELD_SHARE of them, counted from the pose before each) left more
  than MARGIN to spare, the mapping is moved on (the poses are followed sooner).
- **A head held between poses.** A live tracker stamps a pose with the time it describes
  and sends it at once, so it lands as the simulator's clock reaches its time. The
  simulator's clock then runs past it until the next pose lands, and past the newest pose
  the head is held (HeadMotion.pose_at): the hair felt a head that stood still and then
  jumped, once a pose interval. On a smooth turn (0.8 rad at 0.7 Hz) its tips ended 1.3-4.6
  mm from where the same poses, interpolated, put them with the thesis model, and 32-82 mm
  with the articulated one at `motion_smoothing` 0, for trackers at 100 to 30 Hz; the tips'
  acceleration was 6 to 35 times that of the smooth motion (`/tmp` script, 2026-12-01).
  Poses may also land late for good: five nodes and their trackers started together had
  theirs land 20-66 ms behind the simulator's clock, and the mapping was never moved back.
  With `interpolate` the mapping is moved (back, or on) until the pose before each one
  was still ahead of the simulator's clock when it landed, by at most MARGIN (its "slack",
  lead minus the gap between the two stamps, between 0 and MARGIN for the HELD_SHARE
  quantile of the poses: a few stragglers of a jittery transport find the head held), so
  the head is interpolated between poses: the hair follows about one pose interval later
  (10 ms at 100 Hz), at most MAX_BUFFER behind where poses land.
"""

from collections import deque

import numpy as np

WINDOW = 1.0          # s of arrivals the leads are taken over
MIN_SPAN = 0.5        # s of arrivals needed before anything moves
MIN_POSES = 5
MAX_POSES = 4096     # kept at most (a flood of poses keeps the newest)
MARGIN = 0.002        # s of slack the poses may keep before they are followed sooner
RATE = 0.05           # s the mapping moves per s, at most
HELD_SHARE = 0.05     # share of the poses whose previous pose may have been passed (stragglers)
MAX_BUFFER = 0.1      # s poses may land ahead of the simulator's clock by a slew back (10 Hz)
PAUSE = 0.25          # s between two stamps beyond which the tracker paused (no pose interval)


class PoseLead:
    """The leads and slacks of the last WINDOW seconds of poses, and the slew they call for."""

    def __init__(self, interpolate=True):
        self.interpolate = interpolate  # move the mapping back so the head is interpolated
        self._leads = deque(maxlen=MAX_POSES)  # (arrival, lead + shift, gap to the last stamp)
        self._shift = 0.0            # s the mapping was moved on since the anchor
        self._anchor = None          # (HeadMotion, its anchor count) the leads belong to
        self.slewed = 0.0            # s moved on in all (negative: moved back)

    def note(self, motion, arrival, lead, gap=0.0):
        """
        Note a pose's lead (s) under `motion`'s current anchor, arrived at `arrival` (s).

        `gap` is how much later its stamp is than the previous pose's (0 for the first), so
        its slack, lead - gap, is how far ahead of the simulator's clock the previous pose
        still was when this one landed (negative: the head was held there that long).
        A new anchor (a first pose, a clock jump, another simulator) starts afresh: the
        leads under the old one say nothing of the new mapping. So does an arrival before
        the last one: the node's clock jumped back (a looping bag's /clock).
        """
        if gap > PAUSE:
            gap = 0.0             # a tracker that paused (a face out of view): no interval
        anchor = (motion, motion.anchors)
        if anchor != self._anchor or (self._leads and arrival < self._leads[-1][0]):
            self._leads.clear()
            self._shift = 0.0
            self._anchor = anchor
        self._leads.append((arrival, lead + self._shift, gap))

    def _window(self, now):
        """Drop the arrivals older than WINDOW; return the leads and slacks left (arrays)."""
        while self._leads and self._leads[0][0] < now - WINDOW:
            self._leads.popleft()
        n = len(self._leads)
        leads = np.fromiter((lead for _, lead, _ in self._leads), float, n) - self._shift
        return leads, leads - np.fromiter((gap for _, _, gap in self._leads), float, n)

    def least(self, now):
        """Return the least lead (s) of the poses of the last WINDOW seconds, or None."""
        leads, _ = self._window(now)
        return float(leads.min()) if len(leads) else None

    def least_slack(self, now):
        """Return the least slack (s) of the poses of the last WINDOW seconds, or None."""
        _, slacks = self._window(now)
        return float(slacks.min()) if len(slacks) else None

    def slew(self, now, elapsed):
        """
        Return how far (s) to move the mapping on at `now`, `elapsed` s after the last call.

        Zero until MIN_SPAN seconds and MIN_POSES poses were seen under this anchor. Then,
        at most RATE * elapsed: without `interpolate`, on (positive) by the least lead's
        excess over MARGIN; with it, either way, towards the slack all but HELD_SHARE of the
        poses had being between 0 and MARGIN (back, negative, only while poses land less
        than MAX_BUFFER ahead). The caller moves the mapping
        (HairSimulator.shift_pose_clock); the leads noted are counted as moved with it.
        """
        leads, slacks = self._window(now)
        if len(leads) < MIN_POSES or now - self._leads[0][0] < MIN_SPAN:
            return 0.0
        limit = RATE * max(0.0, elapsed)
        if not self.interpolate:
            step = max(0.0, min(float(leads.min()) - MARGIN, limit))
        else:
            k = int(HELD_SHARE * len(slacks))            # the k + 1-th least slack
            slack = float(np.partition(slacks, k)[k])
            step = min(slack - MARGIN, limit)
            if step <= 0.0:
                step = 0.0
                room = MAX_BUFFER - float(leads.min())
                if slack < 0.0 and room > 0.0:
                    step = -min(-slack, limit, room)
        self._shift += step
        self.slewed += step
        return step
