"""
Head motion from stamped poses: pose, velocity and acceleration at simulation times.

Poses arrive stamped (seconds) and are mapped onto the simulator's clock. They may jitter,
repeat, come out of order, jump in time or teleport; each case is sorted here:

- repeated stamps and stamps a little older than the last are dropped (counted);
- a stamp far ahead of or behind the simulator clock, or more than `clock_jump_back`
  seconds older than the last one (a looping bag, a restarted tracker), re-anchors the
  mapping (a clock jump, counted);
- a jump both large (over `TELEPORT_DISTANCE` / `TELEPORT_ANGLE`) and faster than the
  limits is a teleport: the hair is carried rigidly with the head, no inertial kick;
- jitter is smoothed by low-passing the velocity and clamping the acceleration;
- with `head_deadband` and `head_turn_deadband`, a tracker's noise is held out: a pose
  within them of the head leaves it where it is (counted: `held`), one beyond moves it
  only by the excess;
- the very first pose places the head (like a teleport): nothing is known before it.
"""

from collections import deque
import math

from numba import njit
import numpy as np

from hair_sim.physics.inputs import real_array, real_number

TELEPORT_DISTANCE = 0.25     # m: smaller jumps are jitter, whatever their implied speed
TELEPORT_ANGLE = 0.6         # rad
MAX_GAP = 1.0                # s a sample may lag the simulator before re-anchoring
MAX_LEAD = 0.5               # s a sample may run ahead of the simulator before re-anchoring
HISTORY = 32                 # samples kept (bounded memory under floods)


def quat_to_matrix(q):
    """Return the rotation matrix of a unit quaternion (x, y, z, w)."""
    # Python floats: numpy scalars cost 10x an op
    x, y, z, w = np.asarray(q, dtype=np.float64).tolist()
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@njit(cache=True)
def rotation_vector(R):
    """Return the axis-angle vector (rad) of rotation matrix R."""
    c = min(1.0, max(-1.0, (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) * 0.5))
    angle = math.acos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = math.sin(angle)
    if angle < 1e-9:
        return 0.5 * v
    if s < 1e-6:                                   # near pi: axis from the diagonal
        axis = np.empty(3)
        k = 0
        for i in range(3):
            axis[i] = math.sqrt(max((R[i, i] + 1.0) * 0.5, 0.0))
            if axis[i] > axis[k]:
                k = i
        for i in range(3):
            if i != k and R[k, i] + R[i, k] < 0.0:
                axis[i] = -axis[i]
        n = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
        return axis * (angle / n)
    return v * (angle / (2.0 * s))


@njit(cache=True)
def filter_head_motion(new_pose,
                       last,
                       beta,
                       h,
                       limits):
    """
    One step of the head's motion filter: the velocity low-passed, the acceleration clamped.

    From the pose last = (p_old, R_old, v, w), with the filtered linear and angular
    velocities v and w so far, to new_pose = (p_new, R_new) in h seconds; the filter weight
    beta = h / (smoothing + h); limits = (max acceleration, max angular acceleration).
    Returns (kinematics, moved): kinematics rows are the new v, w, a, alpha and the pose's
    own turn over the step, unfiltered (the rotation vector of R_new R_old^T over h, world
    frame: the rate the head turns at between the two poses); moved says whether the pose
    changed by more than 1e-9.
    """
    p_new, R_new = new_pose
    p_old, R_old, v, w = last
    max_acceleration, max_angular_acceleration = limits
    dR = np.empty((3, 3))                          # R_new R_old^T
    for i in range(3):
        for j in range(3):
            dR[i, j] = R_new[i, 0] * R_old[j, 0] + R_new[i, 1] * R_old[j, 1] + \
                R_new[i, 2] * R_old[j, 2]
    rv = rotation_vector(dR)
    out = np.empty((5, 3))
    moved = False
    for k in range(3):
        if abs(p_new[k] - p_old[k]) > 1e-9:
            moved = True
        for j in range(3):
            if abs(R_new[k, j] - R_old[k, j]) > 1e-9:
                moved = True
        out[0, k] = v[k] + beta * ((p_new[k] - p_old[k]) / h - v[k])
        out[1, k] = w[k] + beta * (rv[k] / h - w[k])
        out[2, k] = (out[0, k] - v[k]) / h
        out[3, k] = (out[1, k] - w[k]) / h
        out[4, k] = rv[k] / h
    for row, limit in ((2, max_acceleration), (3, max_angular_acceleration)):
        n = math.sqrt(out[row, 0] ** 2 + out[row, 1] ** 2 + out[row, 2] ** 2)
        if n > limit:
            for k in range(3):
                out[row, k] *= limit / n
    return out, moved


def backlash(position, quaternion, new_position, new_quaternion, deadband, turn_deadband):
    """
    Return the head's pose (position, quaternion) after a pose that may be a tracker's noise.

    The head stays where it is while the new pose is within `deadband` (m) of it and turned
    less than `turn_deadband` (rad) from it; beyond, it moves towards the new pose by the
    excess only (a backlash: it trails a real motion by the deadband, and follows it
    without a jump). The third value is 1 if the pose was held out entirely, else 0.
    """
    offset = new_position - position
    distance = math.sqrt(float(offset @ offset))
    held = 1
    if distance > deadband:
        position = position + offset * (1.0 - deadband / distance)
        held = 0
    angle = 2.0 * math.acos(min(1.0, abs(float(quaternion @ new_quaternion))))
    if angle > turn_deadband:
        quaternion = slerp(quaternion, new_quaternion, 1.0 - turn_deadband / angle)
        held = 0
    return position, quaternion, held


def slerp(q0, q1, f):
    """Spherical interpolation between unit quaternions (x, y, z, w)."""
    d = float(np.dot(q0, q1))
    if d < 0.0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + f * (q1 - q0)
        return q / math.sqrt(float(q @ q))
    th = math.acos(d)
    return (math.sin((1 - f) * th) * q0 + math.sin(f * th) * q1) / math.sin(th)


class HeadMotion:
    """Accept stamped head poses and answer the head pose at a simulator time."""

    def __init__(self, params):
        self.params = params
        self.samples = deque(maxlen=HISTORY)       # (sim time, stamp, position, quaternion)
        self.offset = None                         # stamp - simulator time
        self.anchors = 0                           # times the offset was (re)set from a pose
        self.counts = {'accepted': 0, 'invalid': 0, 'repeated': 0, 'out_of_order': 0,
                       'clock_jump': 0, 'teleport': 0, 'normalised': 0, 'held': 0}
        self.teleported = False

    def reset(self):
        """Forget every sample (the counts stay)."""
        self.samples.clear()
        self.offset = None
        self.teleported = False

    def add(self, stamp, position, quaternion, now):
        """Add a pose stamped `stamp` (s) while the simulator is at `now`; return a verdict."""
        try:
            p = real_array(position, 3, 'position')
            q = real_array(quaternion, 4, 'quaternion')
            stamp = real_number(stamp, 'stamp')
        except ValueError:
            self.counts['invalid'] += 1
            return 'invalid'
        # checked on Python floats: numpy's reductions on 3 and 4 numbers (isfinite().all(),
        # abs().max(), norm) were most of a pose's cost, paid at every step
        px, py, pz = p.tolist()
        qx, qy, qz, qw = q.tolist()
        n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        # (a NaN or infinity anywhere makes the sum of the magnitudes non-finite)
        if not (math.isfinite(abs(px) + abs(py) + abs(pz) + n) and math.isfinite(stamp)) \
                or n < 1e-6 or max(abs(px), abs(py), abs(pz)) > 1e6:
            self.counts['invalid'] += 1
            return 'invalid'
        verdict = 'ok'
        if abs(n - 1.0) > 1e-6:
            self.counts['normalised'] += 1
            verdict = 'normalised'
        q = q / n
        prev = self.samples[-1] if self.samples else None
        if prev is not None:
            last_stamp = prev[1]
            if stamp == last_stamp:
                self.counts['repeated'] += 1
                return 'repeated'
            if stamp < last_stamp:
                if last_stamp - stamp <= self.params.clock_jump_back:
                    self.counts['out_of_order'] += 1
                    return 'out_of_order'
                # a looping bag or a restarted tracker: the clock jumped back; re-anchor
                self.samples.clear()
                self.offset = None
        if self.offset is None:
            # the first pose (or the first after the clock jumped back) anchors the clock
            self.offset = stamp - now
            self.anchors += 1
            if prev is None:                # the very first places the head: no kick
                self.teleported = True
            else:
                self.counts['clock_jump'] += 1
                verdict = 'clock_jump'
        t = stamp - self.offset
        if self.samples and (t > now + MAX_LEAD or t < now - MAX_GAP):
            self.offset = stamp - now
            self.anchors += 1
            t = now
            self.counts['clock_jump'] += 1
            verdict = 'clock_jump'
            while self.samples and self.samples[-1][0] >= t:
                self.samples.pop()
        if prev is not None:
            _, _, p0, q0 = prev
            # the head will cover the jump between now (or the last sample) and t
            dt = max(t - max(self.samples[-1][0], now) if self.samples else t - now, 1e-3)
            (ax, ay, az), (bx, by, bz, bw) = p0.tolist(), q0.tolist()
            dist = math.sqrt((px - ax) ** 2 + (py - ay) ** 2 + (pz - az) ** 2)
            ang = 2.0 * math.acos(min(1.0, abs(qx * bx + qy * by + qz * bz + qw * bw) / n))
            if (dist > TELEPORT_DISTANCE and dist / dt > self.params.max_head_speed) or \
                    (ang > TELEPORT_ANGLE and ang / dt > self.params.max_head_angular_speed):
                self.counts['teleport'] += 1
                self.samples.clear()
                self.teleported = True
                verdict = 'teleport'
        if self.samples and (self.params.head_deadband > 0.0
                             or self.params.head_turn_deadband > 0.0):
            p, q, held = backlash(self.samples[-1][2], self.samples[-1][3], p, q,
                                  self.params.head_deadband, self.params.head_turn_deadband)
            self.counts['held'] += held
        self.samples.append((t, stamp, p, q))
        self.counts['accepted'] += 1
        return verdict

    def skip(self, seconds):
        """
        Shift the mapping by `seconds` the simulator dropped (it could not keep up).

        Pose stamps then keep lining up with the simulator's time. Negative seconds move it
        back: the poses are followed that much later (HairSimulator.shift_pose_clock).
        """
        if self.offset is None or seconds == 0.0:
            return
        self.offset += seconds
        self.samples = deque(((t - seconds, st, p, q) for t, st, p, q in self.samples),
                             maxlen=HISTORY)

    @property
    def newest_stamp(self):
        """Return the stamp of the newest accepted pose, or None."""
        return self.samples[-1][1] if self.samples else None

    def pose_at(self, t):
        """Return (position, quaternion) of the head at simulator time t, or None if unknown."""
        if not self.samples:
            return None
        s = self.samples
        if t >= s[-1][0]:
            return s[-1][2], s[-1][3]
        if t <= s[0][0]:
            return s[0][2], s[0][3]
        for i in range(len(s) - 1, 0, -1):
            if s[i - 1][0] <= t:
                t0, _, p0, q0 = s[i - 1]
                t1, _, p1, q1 = s[i]
                f = (t - t0) / (t1 - t0)
                return p0 + f * (p1 - p0), slerp(q0, q1, f)
        return s[0][2], s[0][3]
