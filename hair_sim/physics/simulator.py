"""
HairSimulator: the driver users call.

It owns the strands, the head's motion, the wind,
the forces pass, sleep and the counters; a strand model (picked by name, like Warp's
integrators) advances the strands under those forces. State lives in contiguous arrays
handed to module-level numba kernels (physics/forces.py, physics/solvers/).
"""

from dataclasses import asdict
import math
import time as _time

import numpy as np

from hair_sim.modeling.head import MAX_SPHERES
from hair_sim.modeling.strips import build_strips
from hair_sim.physics import forces as F
from hair_sim.physics.inputs import index_array, real_array, real_number, shown
from hair_sim.physics.motion import filter_head_motion, HeadMotion, quat_to_matrix
from hair_sim.physics.multirate import multirate_substep
from hair_sim.physics.params import PhysicsParams
from hair_sim.physics.solvers.anjyo import AnjyoSolver
from hair_sim.physics.solvers.articulated import ArticulatedSolver, FREE_CLEARANCE
from hair_sim.physics.wind import Wind
from hair_sim.vecmath import vector_lengths

DEFAULT_DT = 1.0 / 240.0       # s: 4 steps per 60 Hz frame (pendulum period within 1 %)
SUBSTEPS_PER_60HZ_FRAME = int(round(1.0 / (60.0 * DEFAULT_DT)))
MAX_DT = 0.1
MIN_DT = 1e-6                  # s: 10x below the finest step any reference here takes
MAX_REST_EXTENT = 100.0        # m: how far from the head's origin a bare strand may lie
RETRY_SUBSTEP_FACTOR = 4       # a step that came out non-finite is taken again this much finer
# A retry that comes out non-finite too is taken again, RETRY_SUBSTEP_FACTOR times finer
# each time, while a further try costs at most this many segment-substeps (about half a
# second of one core for the articulated chain, forces included), before the hair is put
# back at its rest shape: a few strands on their own may take thousands of substeps, a
# whole shipped style about a thousand
RETRY_MAX_WORK = 1_000_000
STABILITY_MARGIN = 0.9         # explicit terms need omega * dt < 2 * margin
SOLVERS = {'anjyo': AnjyoSolver, 'articulated': ArticulatedSolver}
# The head counts as still (sleep may begin) below these
STILL_SPEED = 1e-4             # m/s and rad/s
STILL_ACCELERATION = 1e-3      # m/s^2
# Angular acceleration is clamped at max_head_acceleration over this lever (m): a point a
# head's radius from the centre then sees no more than max_head_acceleration.
ANGULAR_ACCELERATION_LEVER = 0.1


class SimulationDiverged(RuntimeError):
    """A step produced a non-finite state; the simulator has reset to the rest shape."""


class HairSimulator:
    """
    Simulate every strand of a hairstyle (thesis ch. 4-5).

        sim = HairSimulator(style, model='articulated')
        sim.set_head_pose(t, position_xyz, quaternion_xyzw)
        sim.set_wind((3, 0, 0), turbulence=0.2, seed=1)
        sim.step(1 / 240)
        sim.strand_positions()        # (n_strands, n_vertices, 3), world frame
    """

    def __init__(self, style, **params):
        self._init_common(params)
        strips = build_strips(style)
        self._set_geometry(style, strips.rest.copy(), style.head, strips.neighbor_pairs)
        self.strips = strips

    # ----------------------------------------------------------------- set-up
    @classmethod
    def from_strands(cls, rest, head, pairs=None, **params):
        """
        Simulate bare strands (n_strands, n_vertices, 3, head frame) without a style.

        Raises ValueError unless rest is finite, within MAX_REST_EXTENT m of the head's
        origin and shaped (at least 1, at least 2, 3), and each of pairs (inter-strip
        springs of type 1, (k, 2)) joins two different strands.
        """
        rest = real_array(rest, None, 'rest strands')
        if rest.ndim != 3 or rest.shape[0] < 1 or rest.shape[1] < 2 or rest.shape[2] != 3:
            raise ValueError('rest strands must be shaped (strands >= 1, vertices >= 2, 3), '
                             'not %s' % (rest.shape,))
        if not (np.all(np.isfinite(rest)) and np.abs(rest).max() <= MAX_REST_EXTENT):
            raise ValueError('rest strands must be finite and within %g m of the head'
                             % MAX_REST_EXTENT)
        if pairs is None:
            pairs = np.zeros((0, 2), np.int64)
        else:
            pairs = index_array(pairs, (-1, 2), 'pairs (strand, strand)')
            if len(pairs) and (pairs.min() < 0 or pairs.max() >= rest.shape[0]
                               or np.any(pairs[:, 0] == pairs[:, 1])):
                raise ValueError('pairs must join two different strands of the %d'
                                 % rest.shape[0])
        sim = cls.__new__(cls)
        sim._init_common(params)
        sim._set_geometry(None, rest, head, pairs)
        return sim

    def _init_common(self, params):
        self.params = PhysicsParams().replaced(**params)
        self.motion = HeadMotion(self.params)
        self.wind = Wind()
        self.time = 0.0
        self._constants_of = None          # the params the cached kernel constants are for
        self._springs_rest3 = None
        self.counters = {'steps': 0, 'awake_steps': 0, 'segment_updates': 0,
                         'kernel_calls': 0, 'broad_phase_checks': 0, 'contacts': 0,
                         'diverged': 0,
                         'wall_springs': 0, 'recharts': 0, 'guard_moves': 0, 'wakes': 0,
                         'turn_clamps': 0, 'substeps': 0, 'strand_substeps': 0,
                         'retried_steps': 0, 'outran_kept': 0, 'shortened_steps': 0}
        self.last_step_time = 0.0
        self._head_moved = True             # whether the head moved in the last step
        self.stability_dt = DEFAULT_DT      # the step set_params checks stability at
        self.state_version = 0              # bumped whenever positions may have changed
        self.layout_version = 0             # bumped whenever a kernel argument's type may change
        self.broad_phase = True             # skip spheres a strand cannot reach
        # segment-substeps a step may take at most (None: no limit); a step that would take
        # more simulates less of its time and drops the rest (see step)
        self.max_step_work = None
        self.time_dropped = 0.0             # s of input time dropped (drop_time)
        self._last_substeps = 1             # how many substeps each strand took last step
        self._R = np.eye(3)
        self._p = np.zeros(3)

    def set_style(self, style):
        """
        Tessellate `style` (thesis 6.2) and start its strands at rest under the head.

        All or nothing: the new strands are built and stability-checked off to the side
        and swapped in at once; on any error this simulator is left as it was.
        """
        fresh = HairSimulator(style, **asdict(self.params))
        reason = stability_problem(self.params, fresh, self.stability_dt)
        if reason:
            raise ValueError(reason)
        fresh.adopt(self)
        self.__dict__.update(fresh.__dict__)

    def adopt(self, old):
        """
        Take over `old`'s clock, inputs, head pose, parameters and counters.

        A simulator built off to the side for a new style continues where the running one
        is: the same head motion stream, wind and time; the hair starts at rest under the
        current head pose.
        """
        self.params = old.params
        self.motion = old.motion
        self.motion.params = old.params
        self.wind = old.wind
        self.time = old.time
        self.counters = dict(old.counters)
        self._head_moved = True
        self.stability_dt = old.stability_dt
        self.broad_phase = old.broad_phase
        self.max_step_work = old.max_step_work
        self.time_dropped = old.time_dropped
        self._R, self._p = old._R.copy(), old._p.copy()
        self._make_solver()
        self._place_at_rest()
        self.state_version = old.state_version + 1

    def _set_geometry(self, style, rest, head, pairs):
        """Build every per-segment array from rest strands (head frame)."""
        self.layout_version += 1
        if len(head.collision) > MAX_SPHERES:
            raise ValueError('at most %d collision spheres are supported' % MAX_SPHERES)
        F.guard_rest_shape(rest, np.ascontiguousarray(head.collision))
        seg = np.diff(rest, axis=1)
        length = np.linalg.norm(seg, axis=2)
        if length.min() < 1e-5:
            raise ValueError('a segment is shorter than 0.01 mm')
        self.style = style
        self.strips = None
        self.rest = rest
        self.head = head
        self.root_head = np.ascontiguousarray(rest[:, 0])
        self.modeled_dir = seg / length[..., None]
        self.length = np.ascontiguousarray(length)
        self.reach = length.sum(axis=1)
        self.spheres_head = np.ascontiguousarray(self.head.collision)
        self.n_scalp = len(self.head.scalp)
        n_s, n_seg = length.shape
        self.pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
        self.rest1 = np.linalg.norm(rest[self.pairs[:, 1]] - rest[self.pairs[:, 0]], axis=2) \
            if len(self.pairs) else np.zeros((0, n_seg + 1))
        scalp_head = np.ascontiguousarray(self.head.scalp)
        self.wall_sign = np.ones((len(self.pairs), n_seg + 1, 2))
        self.wall_rest = np.full((len(self.pairs), n_seg + 1, 2), np.inf)
        for q, (a, b) in enumerate(self.pairs):
            for j in range(1, n_seg + 1):
                for side, (me, other) in enumerate(((a, b), (b, a))):
                    sd = F.wall_signed_distance(rest, scalp_head, me, other, j)[0]
                    self.wall_sign[q, j, side] = 1.0 if sd >= 0 else -1.0
                    self.wall_rest[q, j, side] = abs(sd)
        self.rest3 = self._scalp_rest_lengths(self.params.scalp_spring_reach)
        self.pos = np.zeros((n_s, n_seg + 1, 3))
        self.pos_prev = np.zeros_like(self.pos)
        self.vel = np.zeros_like(self.pos)
        self.f_dist = np.zeros((n_s, n_seg, 3))
        self.f_end = np.zeros((n_s, n_seg, 3))
        self.contact = np.zeros((n_s, n_seg, F.CONTACT_SLOTS * F.CONTACT_FIELDS))
        self.masks = np.zeros(n_s, dtype=np.int64)
        self.roots = np.zeros((n_s, 3))
        self.root_vel = np.zeros((n_s, 3))
        self.root_acc = np.zeros((n_s, 3))
        self._proj = np.zeros((n_s, n_seg + 1, 3))
        self._pos_mid = np.zeros((n_s, n_seg + 1, 3))     # where a model takes its forces
        self._snapshot = None                               # _saved()'s buffers
        self._spheres = np.zeros_like(self.spheres_head)
        self._sphere_vel = np.zeros((len(self.spheres_head), 3))
        self.stats = np.zeros(F.N_STATS)
        self._make_solver()
        self._place_at_rest()

    def _derive_masses(self):
        self.mass = self.params.linear_density * self.length
        self.gravity = np.array([0.0, 0.0, -self.params.gravity])

    def _make_solver(self):
        """Build the strand model the parameters name (from masses derived first)."""
        self._derive_masses()
        self.solver = SOLVERS[self.params.model](self)

    def _update_material(self):
        """Recompute masses and the model's constants from the parameters."""
        self._derive_masses()
        self.solver.update_material(self)

    # --------------------------------------------- the kernels' bundles (views, no copies)
    @property
    def strands(self):
        """Return the strands' arrays as the kernels take them."""
        return F.Strands(pos=self.pos, pos_prev=self.pos_prev, vel=self.vel,
                         length=self.length, mass=self.mass)

    @property
    def forces(self):
        """Return the per-segment force arrays (world frame)."""
        return F.Forces(f_dist=self.f_dist, f_end=self.f_end, contact=self.contact)

    @property
    def bodies(self):
        """Return the collision spheres in the world, their velocities and the masks."""
        return F.Bodies(spheres=self._spheres, sphere_vel=self._sphere_vel, masks=self.masks)

    @property
    def attachment(self):
        """Return where roots and spheres sit on the head and where they are this step."""
        return F.Attachment(root_head=self.root_head, spheres_head=self.spheres_head,
                            reach=self.reach, roots=self.roots, root_vel=self.root_vel,
                            root_acc=self.root_acc)

    @property
    def head_kinematics(self):
        """Return the head's pose, velocities and accelerations of this step."""
        return F.HeadKinematics(R=np.ascontiguousarray(self._R), p=self._p, v=self._v,
                                a=self._a, w=self._w, alpha=self._alpha, turn=self._turn,
                                t=self._pose_time)

    # ----------------------------------------------------------------- state
    def _place_at_rest(self):
        """Put every strand at its rest shape under the current head pose, at rest."""
        self.solver.place_at_rest(self)
        self.pos[:] = self.rest @ self._R.T + self._p
        self.pos_prev[:] = self.pos
        self.vel[:] = 0.0
        self._v = np.zeros(3)
        self._w = np.zeros(3)
        self._a = np.zeros(3)
        self._alpha = np.zeros(3)
        self._turn = np.zeros(3)
        self._pose_time = self.time
        self.last_dt = DEFAULT_DT
        self._quiet = 0.0
        self._quiet_ref = None
        self._excursion = 0.0           # farthest a vertex got from _quiet_ref mid-step
        self.sleeping = False
        self._wake_reason = 'start'
        self.state_version += 1
        self.stats[F.MIN_SIN_THETA] = 1.0

    def reset(self, clock=False):
        """
        Put the hair back at its rest shape under the current head pose, awake.

        clock=True also forgets the pose history, so the next pose re-anchors the clock
        (after a tracker restart) and places the head.
        """
        if clock:
            self.motion.reset()
        self._place_at_rest()

    def set_directions(self, directions):
        """
        Place every segment along `directions` (n_strands, n_segments, 3, world), at rest.

        Raises ValueError, the hair left as it was, unless directions has that shape, is
        finite and has no vector of zero (or unrepresentable) length.
        """
        shape = (self.pos.shape[0], self.pos.shape[1] - 1, 3)
        d = real_array(directions, None, 'directions')
        if d.shape != shape:
            raise ValueError('directions must be shaped %s (strands, segments, xyz), not %s'
                             % (shape, d.shape))
        lengths = vector_lengths(d)
        if not np.all(np.isfinite(lengths) & (lengths > 0.0)):
            raise ValueError('directions must be finite vectors of non-zero length')
        d = np.ascontiguousarray(d / lengths[..., None])
        self.solver.place(self, d)
        roots = self.root_head @ self._R.T + self._p
        self.pos[:, 0] = roots
        self.pos[:, 1:] = roots[:, None] + np.cumsum(d * self.length[..., None], axis=1)
        self.pos_prev[:] = self.pos
        self.vel[:] = 0.0
        self.state_version += 1
        self._wake('directions')

    def kinetic_energy(self):
        """Return the kinetic energy (J) of the strands."""
        return self.solver.kinetic_energy(self)

    def energy(self):
        """Return the kinetic, gravitational and spring energies in J; articulated model only."""
        if not isinstance(self.solver, ArticulatedSolver):
            raise ValueError('energy() is defined for the articulated model')
        centres = 0.5 * (self.pos[:, 1:] + self.pos[:, :-1])
        grav = float((self.mass * centres[..., 2]).sum() * self.params.gravity)
        return self.solver.kinetic_energy(self), grav, self.solver.potential_energy(self)

    # ----------------------------------------------------------------- inputs
    def set_head_pose(self, stamp_s, position_xyz, quaternion_xyzw):
        """Add a stamped head pose (world frame); returns the verdict string (see motion)."""
        return self.motion.add(stamp_s, position_xyz, quaternion_xyzw, self.time)

    def set_wind(self, velocity_xyz, turbulence=0.0, seed=0):
        """Set the wind (m/s, world frame); speeds above max_wind_speed are clamped."""
        v = real_array(velocity_xyz, 3, 'wind velocity')
        turbulence = real_number(turbulence, 'turbulence')
        if not np.all(np.isfinite(v)) or not math.isfinite(turbulence):
            raise ValueError('wind must be finite')
        speed = float(vector_lengths(v))
        clamped = speed > self.params.max_wind_speed
        if clamped:
            v *= self.params.max_wind_speed / speed
        turbulence = min(max(turbulence, 0.0), 1.0)
        old = (self.wind.velocity.copy(), self.wind.turbulence, self.wind.seed)
        self.wind.set(v, turbulence, seed)
        # (no layout_version bump: the wind field's arrays and numbers keep their types,
        # Wind.set builds them so, and the kernels take the field on every call. A bump
        # made the next step type every argument again: 0.77 ms, not 0.15, for
        # thesis_long at 1/240 s)
        if not (np.array_equal(old[0], v) and old[1] == turbulence and old[2] == self.wind.seed):
            self._wake('wind')
        return 'clamped' if clamped else 'ok'

    def set_params(self, step_dt=None, **changes):
        """
        Change parameters (validated, stability-checked); the old ones stay on error.

        step_dt: change the planned step too (see plan_step), checked with the new
        parameters. A change of `model` starts the new model from the strands' current
        directions, at rest.
        """
        new = self.params.replaced(**changes)
        dt = self.stability_dt if step_dt is None else _step_length(step_dt)
        reason = stability_problem(new, self, dt)
        if reason:
            raise ValueError(reason)
        model_changed = new.model != self.params.model
        self.stability_dt = dt
        self.params = new
        self.motion.params = new
        if model_changed:
            directions = np.diff(self.pos, axis=1) / self.length[..., None]
            self._make_solver()
            self.solver.place(self, directions)
            self.pos_prev[:] = self.pos
            self.vel[:] = 0.0
        else:
            self._update_material()
        if 'scalp_spring_reach' in changes:
            self.rest3 = self._scalp_rest_lengths(new.scalp_spring_reach)
        self._wake('params')

    def plan_step(self, dt):
        """Set the step later parameter changes are checked at; refuse an unstable one."""
        dt = _step_length(dt)
        reason = stability_problem(self.params, self, dt)
        if reason:
            raise ValueError(reason)
        self.stability_dt = dt

    def skip_time(self, seconds):
        """
        Let `seconds` of input time pass unsimulated (a driver that fell behind drops them).

        The pose clock's mapping moves along, so the next step follows the head pose of
        now, not one `seconds` old, and output stamps stay honest. The caller counts them
        (drop_time counts them in time_dropped).
        """
        self.motion.skip(_time_span(seconds))

    def shift_pose_clock(self, seconds):
        """
        Move the pose clock's mapping by `seconds`, either way; nothing is simulated or dropped.

        Positive: every pose is followed that much sooner (latency no pose needs is taken
        away). Negative: that much later, so that the next pose has landed before the
        simulator's clock passes the newest (the head is then interpolated between poses,
        not held at the newest until the next lands). A driver moves it in small steps (the
        node: at most 5 % of the time passing), as the head's motion plays that much faster
        or slower meanwhile; the output stamps (stamp_at) move with it.
        """
        self.motion.skip(_time_span(seconds, either_way=True))

    def stamp_at(self, t=None):
        """
        Return the head-pose stamp (s) that simulator time t (default: now) corresponds to.

        Poses are mapped onto the simulator's clock by an offset (see HeadMotion); the
        state at time t follows the head pose stamped t + offset, or the newest pose when t
        is past it (the head is held there), so a renderer can line the hair up with the
        head pose it followed. None before any pose arrived.
        """
        offset = self.motion.offset
        if offset is None:
            return None
        stamp = (self.time if t is None else t) + offset
        newest = self.motion.newest_stamp
        # past the newest pose the head is held there: the hair follows no newer pose
        return stamp if newest is None else min(stamp, newest)

    def _scalp_rest_lengths(self, reach):
        """Return the rest length of every vertex's scalp spring (type 3), -1 where none."""
        d3 = np.linalg.norm(self.rest - self.head.nearest_on_scalp(self.rest), axis=2)
        rest3 = np.where(d3 < reach, d3, -1.0)
        rest3[:, 0] = -1.0                 # roots sit on the scalp
        return rest3

    def _wake(self, reason):
        if self.sleeping:
            self.counters['wakes'] += 1
        self.sleeping = False
        self._quiet = 0.0
        self._quiet_ref = None
        self._wake_reason = reason

    # ----------------------------------------------------------------- stepping
    def _advance_head(self, t, h):
        """
        Move the head to its pose at time t; return True if it moved.

        _head_moved says whether it moves during the step (a teleport puts it, and the
        hair with it, where it is before the step: it does not).
        """
        self._turn = np.zeros(3)                  # (unless the head turns in this step)
        self._pose_time = t
        self._head_moved = False
        pose = self.motion.pose_at(t)
        if pose is None:
            return False
        p_new = pose[0]
        R_new = quat_to_matrix(pose[1])
        if self.motion.teleported:                  # carry the hair rigidly, no kick
            self.motion.teleported = False
            dR = R_new @ self._R.T
            self.solver.rotate(dR)
            for arr in (self.pos, self.pos_prev):
                arr[:] = (arr - self._p) @ dR.T + p_new
            self.vel[:] = 0.0
            self._R, self._p = R_new, p_new.copy()
            self.state_version += 1
            self._v[:] = 0.0
            self._w[:] = 0.0
            self._a[:] = 0.0
            self._alpha[:] = 0.0
            self._wake('teleport')
            return True
        p = self.params
        kin, moved = filter_head_motion(
            (p_new, R_new),
            (self._p, self._R, self._v, self._w),
            h / (p.motion_smoothing + h),
            h,
            (p.max_head_acceleration, p.max_head_acceleration / ANGULAR_ACCELERATION_LEVER),
        )
        # (and the pose's own turn over the step, at a constant rate, world frame: where
        # the head is between the two poses, the base the chains' roots are jointed to)
        self._v, self._w, self._a, self._alpha, self._turn = kin
        self._R, self._p = R_new, p_new.copy()
        self._head_moved = bool(moved)
        return moved

    def _head_still(self):
        return (np.abs(self._v).max() < STILL_SPEED and np.abs(self._w).max() < STILL_SPEED
                and np.abs(self._a).max() < STILL_ACCELERATION)

    def step(self, dt=DEFAULT_DT):
        """
        Advance the simulation by dt seconds of input time; return False when asleep.

        With max_step_work set, a step whose substeps would update more segments than
        that (the articulated model's whipping tips) simulates the share of dt that fits
        and drops the rest of it, as a driver that falls behind does (drop_time): the
        head's motion is followed as it was up to there, the pose clock then moves on, and
        time_dropped counts it. Each substep keeps its length, so stability is unchanged.
        """
        dt = _step_length(dt)
        t0 = _time.perf_counter()
        h = self._affordable(dt)
        dropped = self.time_dropped
        t = self.time + h
        self.counters['steps'] += 1
        # (a retry cut to max_step_work takes the head again from here; not after a
        # teleport, which carries the hair with the head before the step)
        head = self._head_state() if self.max_step_work is not None and \
            not self.motion.teleported else None
        moved = self._advance_head(t, h)
        if moved:
            self._wake('head')
        if self.sleeping and self.wind.steady and (moved or not self._head_still()):
            self._wake('head')
        if self.sleeping and not self.wind.steady:
            self._wake('wind')
        if self.sleeping:
            self.time = t
            self.last_step_time = _time.perf_counter() - t0
            return False
        try:
            return self._awake_step(t, h, t0, head)
        finally:
            if h < dt:
                self.drop_time(dt - h)
            if self.time_dropped > dropped:      # (once, cut here or its retry cut, or both)
                self.counters['shortened_steps'] += 1

    def _affordable(self, h):
        """
        Return the share of a step of h whose substeps fit max_step_work (h: all of it).

        A strand's substep count grows with the step's length (substeps_for), so the step
        is cut in proportion, down to one substep of the strand that needs the most. The
        counts are capped (MAX_SUBSTEPS), so a cut step's counts can still be over: it is
        cut again, a few times at most.
        """
        cap = self.max_step_work
        if cap is None or self.sleeping:
            return h
        for _ in range(4):
            counts = self.solver.substeps_for(h)
            finest = int(counts.max())
            if finest <= 1:
                return h
            per_strand = finest * len(counts) if self._joined() else int(counts.sum())
            work = per_strand * (self.pos.shape[1] - 1)
            if work <= cap:
                return h
            h *= max(cap / work, 1.0 / finest)
        return h

    def _awake_step(self, t, h, t0, head):
        """
        Simulate the step of h ending at t (awake, begun at perf_counter t0); return True.

        head: the head's state before the step (_head_state; None without max_step_work
        or after a teleport), for a retry cut to max_step_work (_cut_retry).
        """
        saved = self._saved() if self.solver.retries_diverged_steps else None
        finite = self._simulated(t, h)
        if saved is not None:
            # a contact or a whip the substep count did not foresee: take the step again
            # from the saved state: at RETRY_SUBSTEP_FACTOR times the finest count when the
            # state came out non-finite (every strand, or, strands not joined by springs,
            # each that did, the others at their counts); at the counts below when a strand
            # ended the step swinging OUTRAN_FACTOR times faster than its count allows (a
            # blow-up that has not reached inf yet: in the stress bench's gale without
            # inter-strip springs, a strand taking 32 substeps where the finest took 256
            # reached 590 m/s, then NaN)
            counts = self._last_substeps
            finest = int(np.max(counts))
            again = None
            if not finite:
                again = self._finer_counts(self._nonfinite_strands())
            else:
                outran = self._outran(saved, h, counts)
                if outran.any():
                    # what the swings at the step's end need. Strands joined by springs
                    # (sharing a count) take the most any needs: a style at rest (1
                    # substep) hit by a 30 m/s gale and a violent start ended its first
                    # 1/60 s step at 500 rad/s, unretried, and the next step diverged at
                    # any count (thesis_short and bob_fringe, `hair_sim_bench settle`).
                    # Strands at their own counts: each that outran its count takes what
                    # its own swing needs, the others their counts again, so that each
                    # still moves as it would alone (every strand at the finest, as
                    # before, let the hanging scene's top strand, the finest at 16, end a
                    # step at 5e5 rad/s, take it at 16 again, and diverge the next step:
                    # 200 x 20 at 1/60 s)
                    need = self.solver.substeps_for(h)
                    if self._joined():
                        again = max(finest, int(np.max(need)))
                    else:
                        again = np.where(outran, np.maximum(need, counts), counts)
            # a whip that grows within the step (a stiff follicle let go far from its
            # rest: the count is set from the swing where the step starts) can blow up at
            # the finer count too, and not at a finer one still (/tmp script: one strand,
            # root stiffness 1e3 let go at 1 rad, 1/60 s: finite at 1, 2 and 100 substeps,
            # NaN at 12 to 64)
            # A retry that comes out finite but outran its own counts is on its way to a
            # blow-up too (the next step's: a crumpled placement on a clamped follicle,
            # /tmp script, ended a retry at 1024 substeps finite with 2.85e35 J and the
            # next step diverged): it is taken finer again the same way. Past the budget a
            # finite state is kept, as before.
            if again is not None:
                if head is not None:
                    t, h, again = self._cut_retry(head, t, h, again)
                finite = self._take_again(saved, t, h, again)
                while True:
                    if finite:
                        spoiled = self._outran(saved, h, self._last_substeps)
                        if not spoiled.any():
                            break
                    else:
                        spoiled = self._nonfinite_strands()
                    again = self._finer_counts(spoiled)
                    if self._retry_work(again) > RETRY_MAX_WORK:
                        if finite:              # (the retry before: the finest in budget)
                            self.counters['outran_kept'] += 1
                        break
                    finite = self._take_again(saved, t, h, again)
        if not finite:
            self.counters['diverged'] += 1
            self.reset()
            raise SimulationDiverged(
                'the %s model diverged at t = %.3f s (dt %.4g s); the hair was put back at '
                'its rest shape under the current head' % (self.params.model, t, h))
        self.solver.relax_material(h)           # (a material change under way: see there)
        # Settled: with steady inputs, no vertex has left a sleep_tolerance ball around where
        # it was when the quiet window began, for sleep_delay seconds. (A displacement
        # window, not a speed: contact can make a vertex tremble by the guard's 0.2 mm.)
        # (a step taken in substeps one call each is judged at every substep's end too: a
        # tip flipping between two places every substep is in the same one at every step's
        # end, and looked asleep: the thesis model's explicit integrator at 3 times the
        # hinge stiffness, 1/30 s in substeps of 1/120 s, moved 14 mm a substep, and slept)
        inputs_steady = self.wind.steady and self._head_still() and not self.solver.blending
        excursion, self._excursion = self._excursion, 0.0
        if inputs_steady and self._quiet_ref is not None and \
                max(np.abs(self.pos - self._quiet_ref).max(), excursion) < \
                self.params.sleep_tolerance:
            self._quiet += h
            if self._quiet >= self.params.sleep_delay:
                self.sleeping = True
                self.solver.hold()
                self.pos_prev[:] = self.pos
                self.vel[:] = 0.0
        else:
            self._quiet = 0.0
            self._quiet_ref = self.pos.copy() if inputs_steady else None
        self.time = t
        self.last_step_time = _time.perf_counter() - t0
        return True

    def _simulate(self, t, h, at_least=1, shared=False):
        """
        One awake step: the shared forces (eqs. 5, 7-11), then the strand model.

        A model may ask for the step to be split per strand (the articulated chain does
        where a segment would turn too far in one step), into at least `at_least`
        substeps (one for all, or each strand's); every substep recomputes the forces.
        When inter-strip springs join strands (every shipped style), every strand takes
        the largest count, as before multirate: giving each group of joined strands its
        own (tried) left the stress bench's articulated gale as it was but made its random
        motion end with strands balanced that fell during the 4 s sleep window, at 1/1000
        and 1/60 s (the hold itself took 1 substep a strand: the trajectory changed, not
        the stability). Strands on their own (no springs) each take their own count
        (multirate): the step runs as many substeps as the finest strand takes, and each
        strand moves at the substeps in which one of its own ends, by its own length
        (waiting at the others; multirate.multirate_substep), with the wind of its own
        substep's end, so a strand at rest beside a whipping one takes the step whole,
        exactly as it would alone (`shared` makes every strand take the largest). Returns
        each strand's count.
        """
        counts = np.maximum(self.solver.substeps_for(h), at_least)
        n = int(counts.max())
        if n > 1 and (shared or self._joined()):
            counts = np.full_like(counts, n)
        # (before the kernels run: a retry takes its counts from these even when a kernel
        # raised, or it would take the failed counts again and again)
        self._last_substeps = counts
        if self.solver.whole_step:                 # every substep in one kernel call
            self._whole_step(t, h, n, counts)
        elif n == 1:                               # (the usual step: whole)
            whole = np.full(len(counts), h)
            self._substep(t - h + h / n, h, whole, whole)
        else:
            own_h = h / counts
            strand_h, strand_t = np.empty(len(counts)), np.empty(len(counts))
            for k in range(n):                     # (the schedule chain_step runs too)
                multirate_substep((float(t), h, n), k, counts, strand_h, strand_t)
                self._substep(t - h + (k + 1) * h / n, h / n, strand_h, own_h, strand_t)
                if k < n - 1 and self._quiet_ref is not None:      # (sleep: _awake_step)
                    self._excursion = max(self._excursion,
                                          float(np.abs(self.pos - self._quiet_ref).max()))
        self.counters['substeps'] += n
        self.counters['strand_substeps'] += int(counts.sum())
        return counts

    def _outran(self, saved, h, counts):
        """
        Return which strands outran the step just taken (h, at counts) (n_strands,).

        By their swing at its end (the model's outran), or by energy nothing gave them
        (_gained_energy); saved is the state where it began.
        """
        return self.solver.outran(h, counts) | self._gained_energy(saved, h, counts)

    def _gained_energy(self, saved, h, counts):
        """
        Return which strands ended the step just taken (h, at counts) with energy nothing gave.

        Looked for only where nothing could give a strand energy (the head still, no wind,
        no material blended in, no spring to another strand: _passive), among the strands
        whose swing at the step's end asks for more substeps than they took (the model's
        sped_up: a strand whose count covered its swing throughout took the step fine
        enough) with no vertex within FREE_CLEARANCE of a sphere where the step began or
        ended (contact is left out). Those whose motion, weight and springs together end
        above where they began (the model's gained_energy, from the saved state) took the
        step too coarsely, as a strand that outran its count. (n_strands,)
        """
        if not self._passive():
            return np.zeros(self.pos.shape[0], dtype=bool)
        # the snapshot, as _step_state lists it
        pos0, _, vel0, _ = saved[0][:4]
        which = self.solver.sped_up(h, counts)
        if which.any() and self.params.collisions:
            for pos in (pos0, self.pos):               # where the step began, and ended
                F.keep_strands_clear_of_spheres(pos, self.bodies.spheres, FREE_CLEARANCE,
                                                which)
        if not which.any():
            return which
        return self.solver.gained_energy(self, (pos0, vel0), saved[0][4:], which)

    def _passive(self):
        """
        Return whether nothing could give the strands energy in the step just taken.

        Not while the head moved or moves, the wind blows, a material change is blended
        in, or inter-strip springs join strands (their wall springs are no potential's).
        """
        return not (self._head_moved or self.wind.active or self.solver.blending
                    or self._joined() or not self._head_still())

    def _joined(self):
        """Return whether inter-strip springs join strands (they then share a count)."""
        return bool(self.params.inter_strip and len(self.pairs))

    def _nonfinite_strands(self):
        """Return which strands came out of a step non-finite (n_strands,)."""
        return ~np.isfinite(self.pos[:, -1]).all(axis=1)

    def _finer_counts(self, spoiled):
        """
        Return the substep counts to take a step again at after it came out spoiled.

        RETRY_SUBSTEP_FACTOR times the finest count it took: for every strand (a number),
        or, strands not joined by springs, for each that is spoiled (non-finite, or out
        of its count: the mask spoiled), the others at the counts they took (an array).
        """
        counts = self._last_substeps
        again = RETRY_SUBSTEP_FACTOR * int(np.max(counts))
        if not self._joined() and spoiled.any():   # (strands apart: the others as they were)
            return np.where(spoiled, again, counts)
        return again

    def _take_again(self, saved, t, h, counts):
        """Put the state back as the step found it and take it at counts; return finite."""
        self._restore(saved)
        self.counters['retried_steps'] += 1
        return self._simulated(t, h, counts, shared=np.ndim(counts) == 0)

    def _retry_work(self, counts):
        """Return the segment-substeps of a step taken at counts (a number, or per strand)."""
        per_strand = np.broadcast_to(counts, (self.pos.shape[0],))
        return int(np.sum(per_strand)) * (self.pos.shape[1] - 1)

    def _head_state(self):
        """Return copies of what _advance_head changes (the head's pose and motion)."""
        return (self._R.copy(), self._p.copy(), self._v.copy(), self._w.copy(),
                self._a.copy(), self._alpha.copy(), self._turn.copy(), self._pose_time,
                self._head_moved)

    def _cut_retry(self, head, t, h, counts):
        """
        Return (t, h, counts) of a retry that fits max_step_work: the step cut if it must be.

        A retry takes the counts the swing at the first try's end needs, and those can be
        far over the bound: a style at rest hit by a 40 m/s gale took its first 1/60 s step
        at 1 substep, outran it and was taken again at about 230 (212 796 segment-substeps
        in 0.15-0.26 s, over ten times a node's frame share; /tmp script, 2026-11-30). As
        step() does for a step that would not fit, the retry then simulates the share of
        the step that fits, with substeps no longer than the counts give (each count
        scaled and rounded up), and the rest of the step is dropped (shortened_steps,
        time_dropped; the pose clock moves on). The head is taken again to its pose at the
        cut step's end.
        A cut retry that outruns its counts again is taken finer within RETRY_MAX_WORK, as
        any retry is, not within max_step_work: that is the stability net.
        """
        cap = self.max_step_work
        work = self._retry_work(counts)
        if cap is None or work <= cap:
            return t, h, counts
        finest = int(np.max(counts))
        share = max(cap / work, 1.0 / finest)       # at least one substep of the finest
        cut = np.maximum(1, np.ceil(np.asarray(counts) * share)).astype(np.int64)
        counts = int(cut) if np.ndim(counts) == 0 else cut
        kept = h * share
        (self._R, self._p, self._v, self._w, self._a, self._alpha, self._turn,
         self._pose_time, self._head_moved) = head
        t = self.time + kept
        self._advance_head(t, kept)
        self.drop_time(h - kept)
        return t, kept, counts

    def drop_time(self, seconds):
        """
        Drop `seconds` of input time unsimulated: time_dropped counts them (skip_time does not).

        A step cut to max_step_work drops the rest of its time here, and so does a driver
        out of its share of the wall time (the node's steps not taken); the pose clock
        moves on, as in skip_time.
        """
        seconds = _time_span(seconds)
        self.time_dropped += seconds
        self.motion.skip(seconds)

    def _simulated(self, t, h, at_least=1, shared=False):
        """Run _simulate; return whether the state came out finite."""
        try:
            self._simulate(t, h, at_least, shared)
            # vertices are placed root to tip, so a NaN anywhere reaches the tips
            return math.isfinite(self.pos[:, -1].sum())     # NaN and inf survive a sum
        except (ZeroDivisionError, FloatingPointError, OverflowError):
            return False

    def _step_state(self):
        """Return the arrays a step changes: strands, stats and the model's own state."""
        return (self.pos, self.pos_prev, self.vel, self.stats) + self.solver.step_state()

    def _saved(self):
        """
        Copy what a step changes into buffers kept for it; return them and the last dt.

        One snapshot at a time: fresh arrays of this size cost page faults on every step.
        """
        arrays = self._step_state()
        if self._snapshot is None or [b.shape for b in self._snapshot] != \
                [a.shape for a in arrays]:
            self._snapshot = tuple(np.empty_like(a) for a in arrays)
        for dst, src in zip(self._snapshot, arrays):
            np.copyto(dst, src)
        return self._snapshot, self.last_dt

    def _restore(self, saved):
        buffers, self.last_dt = saved
        for dst, src in zip(self._step_state(), buffers):
            np.copyto(dst, src)

    def _cache_constants(self):
        """Build the kernels' constant bundles again (the parameters or rest lengths changed)."""
        self.layout_version += 1
        p = self.params
        self._drag_factor = 0.5 * p.air_density * p.drag_coefficient * p.drag_width
        self._spring_constants = F.SpringConstants(neighbor=p.neighbor_stiffness,
                                                   wall=p.wall_stiffness,
                                                   wall_distance=p.wall_distance,
                                                   scalp=p.scalp_stiffness)
        # the chain holds its modeled shape (sag-free): a wall spring there would push it
        # off (measured: thesis_short drifted 29 mm in 8 s); the thesis model keeps d2
        wall_rest = self.wall_rest if self.solver.holds_modeled_walls else \
            np.full_like(self.wall_rest, np.inf)
        self._strip_springs = F.StripSprings(pairs=self.pairs, rest1=self.rest1,
                                             wall_sign=self.wall_sign, wall_rest=wall_rest,
                                             rest3=self.rest3,
                                             proj=self._proj)
        self._constants_of = p
        self._springs_rest3 = self.rest3

    def _substep(self, t, h, strand_h, own_h, strand_t=None):
        """
        One substep of length h ending at t: strand i moves by strand_h[i] (0: it waits).

        own_h[i] is strand i's own substep, the one it is in (forces at its middle), and
        strand_t[i], if given, when it ends (the wind's time; else t). A fused model (one
        kernel call for the whole step) takes every strand by h.
        """
        c = self.counters
        head, bodies, settings = self._kernel_inputs(t)
        if self.solver.fused:                  # the whole step in one kernel call
            checks, contacts, walls, segments = self.solver.substep(self, h, head, bodies,
                                                                    settings)
            c['kernel_calls'] += 1
        else:
            checks, contacts, walls, segments = self._substep_by_kernel(strand_h, own_h, head,
                                                                        bodies, settings,
                                                                        strand_t)
        self._count_substeps(1, h, (checks, contacts, walls, segments))

    def _whole_step(self, t, h, n, counts):
        """
        Take a step of n substeps ending at t in one call of the model's kernel (whole_step).

        Strand i takes counts[i] of them (at most n), each h / counts[i] long, as _simulate
        does one by one.
        """
        head, bodies, settings = self._kernel_inputs(t - h + h / n)
        step = (float(t), h, n, bool(self.solver.forces_at_mid_step))
        done = self.solver.simulate(self, step, counts, head, bodies, settings)
        self.counters['kernel_calls'] += 1
        self._count_substeps(n, h / n, done)

    def _count_substeps(self, n, h, done):
        """Count n substeps of h that did done = (checks, contacts, walls, segments)."""
        c = self.counters
        checks, contacts, walls, segments = done
        c['broad_phase_checks'] += checks
        c['contacts'] += contacts
        c['wall_springs'] += walls
        c['segment_updates'] += segments
        c['awake_steps'] += n
        self.state_version += n
        c['recharts'] = int(self.stats[F.RECHARTS])
        c['guard_moves'] = int(self.stats[F.GUARD_MOVES])
        c['turn_clamps'] = int(self.stats[F.TURN_CLAMPS])
        self.last_dt = h

    def _kernel_inputs(self, t):
        """Return the head's kinematics, the bodies and the ForceSettings of a (sub)step at t."""
        p = self.params
        if self._constants_of is not p or self._springs_rest3 is not self.rest3:
            self._cache_constants()
        head = self.head_kinematics
        bodies = self.bodies
        settings = F.ForceSettings(
            t=t,
            gravity=self.gravity,
            wind_on=self.wind.active,
            drag_factor=self._drag_factor,
            air_damping=self.solver.air_damping_rate(p),
            collisions=p.collisions,
            broad_phase=self.broad_phase,
            collision_stiffness=p.collision_stiffness,
            collision_damping=p.collision_damping
            + self.solver.contact_damping_rate * p.linear_density,
            inter_strip=p.inter_strip,
            n_scalp=self.n_scalp,
        )
        return head, bodies, settings

    def _substep_by_kernel(self, strand_h, own_h, head, bodies, settings, strand_t=None):
        """Run the shared force kernels one by one, then the model's step (see _substep)."""
        c = self.counters
        attach = self.attachment
        checks = F.place_with_head(
            head,
            attach,
            bodies,
            settings.collisions,
            settings.broad_phase,
        )
        contacts = walls = 0
        self.solver.velocities(self, self.last_dt)
        strands = self.strands
        if self.solver.forces_at_mid_step:      # (Stormer-Verlet: see solvers/articulated)
            # each strand at the middle of its own substep (one waiting: of its next)
            np.multiply(self.vel, 0.5 * own_h[:, None, None], out=self._pos_mid)
            self._pos_mid += self.pos
            strands = strands._replace(pos=self._pos_mid)
        forces = self.forces
        F.external_forces(
            strands,
            attach.root_acc,
            settings.gravity,
            self.wind.field,
            settings.wind_on or self.solver.still_air_drag,
            settings.t,
            settings.drag_factor,
            settings.air_damping,
            self.solver.root_inertia,
            forces,
            (strand_h, strand_t),
        )
        c['kernel_calls'] += 1
        if self.solver.uses_contacts and not settings.collisions:   # (else the kernel does)
            F.clear_contact_record(self.contact)
        if self.solver.springs_before_contacts:
            walls = self._strip_springs_pass(strands, bodies, forces, settings)
        if settings.collisions:
            contacts = F.reaction_constraint_forces(
                strands,
                bodies,
                settings.collision_stiffness,
                settings.collision_damping,
                self.solver.uses_contacts,
                forces,
                self.solver.contact_hinge(head, float(strand_h[0]), self.last_dt,
                                          self.params),
                strand_h,
                self.solver.drops_inward_input,
                self.solver.contact_force_at_q,
            )
            c['kernel_calls'] += 1
        if not self.solver.springs_before_contacts:
            walls = self._strip_springs_pass(strands, bodies, forces, settings)
        if strand_t is None:                    # (every strand ends with the substep)
            strand_t = np.full(len(strand_h), settings.t)
        segments = self.solver.step(self, strand_h, head, strand_t)
        c['kernel_calls'] += 1
        return checks, contacts, walls, segments

    def _strip_springs_pass(self, strands, bodies, forces, settings):
        """Add the springs of thesis 5.2 to the forces; return the wall springs inserted."""
        if not (settings.inter_strip and len(self.pairs)):
            return 0
        self.counters['kernel_calls'] += 1
        return F.strip_springs(
            strands,
            bodies.spheres[:settings.n_scalp],
            self._strip_springs,
            self._spring_constants,
            forces,
        )

    # ----------------------------------------------------------------- outputs
    def strand_positions(self):
        """Return a copy of the strand vertices, (n_strands, n_vertices, 3), world frame."""
        return self.pos.copy()

    @property
    def head_pose(self):
        """Return the (rotation matrix, position) of the head the hair last followed."""
        return self._R.copy(), self._p.copy()

    def positions_in_head_frame(self):
        """Return the strand vertices in the head frame."""
        return (self.pos - self._p) @ self._R

    @property
    def min_sin_theta(self):
        """Return the smallest sin(theta) any segment has had (distance from the poles)."""
        return float(self.stats[F.MIN_SIN_THETA])

    def diagnostics(self):
        """Return the counters and the head-motion verdict counts, for a status report."""
        out = dict(self.counters)
        out.update({'pose_' + k: v for k, v in self.motion.counts.items()})
        # articulated: the share of joints made stiffer than the material to hold the style
        # (MAX_PRELOAD) or to keep it stable, and of strands stiffened for stability
        out['stiffened_joints'] = round(getattr(self.solver, 'stiffened', 0.0), 4)
        out['stabilized_strands'] = round(getattr(self.solver, 'stabilized', 0.0), 4)
        out['time_dropped_s'] = round(self.time_dropped, 3)
        return out


def stability_problem(params, sim, dt):
    """
    Return why `params` would be unstable at step dt for sim's strands, or None.

    sim: a simulator, or the (n_strands, n_segments) segment lengths of a style.
    """
    length = np.asarray(getattr(sim, 'length', sim), dtype=np.float64)
    return SOLVERS[params.model].stability_problem(params, length, dt, STABILITY_MARGIN)


def _time_span(seconds, either_way=False):
    """
    Return `seconds` as a float; raise ValueError unless it is finite and not negative.

    either_way: a negative span is taken too (a shift of the pose clock back).
    """
    s = real_number(seconds, 'seconds')
    if not (math.isfinite(s) and (either_way or s >= 0.0)):
        raise ValueError('seconds must be finite%s, not %r'
                         % ('' if either_way else ' and not negative', seconds))
    return s


def _step_length(dt):
    """
    Return dt as a float; raise ValueError unless it is a step, in [MIN_DT, MAX_DT] s.

    (set_params' step_dt and plan_step took NaN, 0 and -1: every later stability check
    then passed, as nothing compares true with NaN. A string is no step either: step('0.1')
    stepped 0.1 s and then raised a TypeError, the state changed by a call that failed.
    Steps of 1e-200 s and below put the thesis model's velocities, (x - x-) / h, out of
    range: SimulationDiverged, and the hair put back at its rest shape. An int past a
    float's range raised OverflowError.)
    """
    try:
        h = math.nan if isinstance(dt, (str, bytes, bytearray)) else float(dt)
    except (TypeError, ValueError, OverflowError):
        h = math.nan
    if not (math.isfinite(h) and MIN_DT <= h <= MAX_DT):
        raise ValueError('dt must be in [%g, %g] s, not %s' % (MIN_DT, MAX_DT, shown(dt)))
    return h
