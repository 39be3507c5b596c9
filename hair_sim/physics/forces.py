"""
Per-segment world forces both strand models share, and the contact geometry (thesis 4-5).

Every kernel here reads the strands' vertices and velocities and writes forces in the
world frame into `Forces`: `f_dist` (n_strands, n_segments, 3), spread uniformly along a
segment (its resultant acts at the centre), and `f_end`, acting at the segment's end
vertex. The Anjyo solver turns them into the moments of eq. 4; the articulated solver
applies them to its links. Also here: the head's kinematics at the roots and spheres, the
collision broad phase, the reaction constraint of eqs. 7-10, the springs of eq. 11 and the
position guard that keeps vertices out of spheres. State goes in as namedtuples of arrays
(numba passes them like plain arguments); kernels write in place.
"""

from collections import namedtuple
from math import acos, atan2, pi, sqrt

import numpy as np

from hair_sim.kernels import njit_without_refcounts
from hair_sim.vecmath import (nearest_on_spheres, perpendicular_unit, sin_vectorizable,
                              wrap_angle)

GUARD_MARGIN = 2e-4          # m: guard_segment's default lift, and the contact weight's
#                              full-contact band (_contact_weight)
# m: how far outside a sphere the position guard puts a vertex it turns out, in both
# models. A lift of 0.2 mm (GUARD_MARGIN, the thesis model's until 2026-11-26) is work
# done against a spring that presses the vertex onto the head: the spring pushes it back
# in, the guard lifts it out again, and that work fed limit cycles. In the chain: after
# the stress bench's random motion a thesis_long strand rang for ever (its tip 0.6 mm
# peak to peak at 4.6 Hz); with the vertex put back 1 um out the same strands slept 2.9 s
# after the head stopped. In the thesis model (with WALL_PUSH_CAP and _stopped_keep), in
# 24 thesis_long runs like `hair_sim_bench settle`'s at 1/60 s (seeds 1-8), 1 never slept
# with the 0.2 mm lift and 0 with 1 um.
GUARD_LIFT = 1e-6
SEGMENT_TOLERANCE = 2e-4     # m: a segment's inner point deeper than this is pushed out
CONTACT_SKIN = 1e-3          # m: within this of a surface a vertex counts as in contact for
#                              eq. 7, so hair resting on the head (just outside, where the
#                              guard leaves it) keeps its inward force removed and settles
GUARD_PASSES = 12            # guard sweeps over the spheres: a vertex pushed out of one sphere
#                              into a neighbour is pushed again (a crease needs a few)
START_INSIDE = 1e-4          # m: a segment whose start is this deep in a sphere is left alone
# Type-2 springs (thesis 5.2) fade in and out along the projected wall of their neighbour:
# full strength from `along` = 0 to 1 (the top vertex Q down to its projection Q'), ramping
# to nothing over a quarter of the wall's height beyond either end.
WALL_TAPER_SLOPE = 4.0
WALL_TAPER_REACH = 0.25
# A type-2 spring pushes a vertex back to d2 from the wall, -k x with x how far it is
# short of d2; x is capped at this many d2 (a vertex d2 or more past the wall is pushed
# as if it were d2 past). Uncapped, a vertex far past the plane of a wall (seen: 14-21 mm
# past the 0.2 mm wall of a neighbour lying on the scalp, after a gale threw strips over
# each other) got 8-11 times the push of one at the wall, an explicit kick every step:
# in 24 thesis_long runs like `hair_sim_bench settle`'s at 1/60 s (seeds 1-8), 3 never
# slept uncapped and 0 capped (both with GUARD_LIFT and anjyo._stopped_keep). Strips keep
# their sides as well as before: the suite's wall-penetration measure with the springs on
# is 0.35 of off, as uncapped; dropping the spring past d2 instead let them cross (0.71).
WALL_PUSH_CAP = 2.0

# Slots of the solvers' `stats` array (what a step measured, for counters and tests)
MAX_RATE = 0                 # fastest speed of a segment's end about its start (m/s)
RECHARTS = 1                 # polar charts re-centred (Anjyo model)
GUARD_MOVES = 2              # segments the position guard turned out of a sphere
MIN_SIN_THETA = 3            # smallest sin(theta) eqs. 1-6 were evaluated at (Anjyo model)
TURN_CLAMPS = 4              # steps clamped to MAX_TURN (Anjyo model)
N_STATS = 5

HeadKinematics = namedtuple('HeadKinematics', ['R', 'p', 'v', 'a', 'w', 'alpha', 'turn',
                                               't'])
Strands = namedtuple('Strands', ['pos', 'pos_prev', 'vel', 'length', 'mass'])
Bodies = namedtuple('Bodies', ['spheres', 'sphere_vel', 'masks'])
# contact: per segment, the stiffness and damping (N/m, N s/m) of its contact with a sphere,
# the contact's normal and its lever along the segment (0..1); a model may treat them
# implicitly (the articulated chain does)
Forces = namedtuple('Forces', ['f_dist', 'f_end', 'contact'])
# The contact record of each segment, for a model that takes contacts implicitly: up to
# CONTACT_SLOTS contacts (a vertex in a crease between two spheres and the segment's
# chord on a third), each as CONTACT_FIELDS numbers. A contact left out of the record keeps
# its damping explicit, and that is unstable for a light segment (h c / m is about 4 at
# 1/60 s): with one slot, a tip touching one sphere with its end and another with its
# chord was flung at 10 rad/s from 2 in one step.
(CONTACT_K, CONTACT_C, CONTACT_NX, CONTACT_NY, CONTACT_NZ, CONTACT_LEVER, CONTACT_SPHERE,
 CONTACT_LOAD, CONTACT_LOAD_MID) = range(9)
CONTACT_FIELDS = 9
CONTACT_SLOTS = 3
# the modes' wave vectors by axis (3, modes), and scratch (2, modes): each mode's phase at
# the step's time and its gust at a strand
WindField = namedtuple('WindField', ['velocity', 'amplitude', 'mode_dir', 'mode_k_by_axis',
                                     'mode_w', 'mode_phase', 'scratch'])
# wall_rest: per pair, vertex and side, the distance within which a type-2 spring acts
# at most (inf: the thesis' d2 alone; the articulated model: also at most the modeled one)
StripSprings = namedtuple('StripSprings', ['pairs', 'rest1', 'wall_sign', 'wall_rest', 'rest3',
                                           'proj'])
SpringConstants = namedtuple('SpringConstants', ['neighbor', 'wall', 'wall_distance',
                                                 'scalp'])
# where the roots and spheres sit on the head, and where they are this step
Attachment = namedtuple('Attachment', ['root_head', 'spheres_head', 'reach', 'roots',
                                       'root_vel', 'root_acc'])
# what one step of the shared forces needs besides the state (scalars, built per step)
ForceSettings = namedtuple('ForceSettings', ['t', 'gravity', 'wind_on', 'drag_factor',
                                             'air_damping', 'collisions', 'broad_phase',
                                             'collision_stiffness', 'collision_damping',
                                             'inter_strip', 'n_scalp'])


@njit_without_refcounts
def rotate(R, x, y, z):
    """Return R (x, y, z)."""
    return (R[0, 0] * x + R[0, 1] * y + R[0, 2] * z, R[1, 0] * x + R[1, 1] * y + R[1, 2] * z,
            R[2, 0] * x + R[2, 1] * y + R[2, 2] * z)


@njit_without_refcounts
def root_kinematics(head,
                    root_head,
                    spheres_head,
                    roots,
                    root_vel,
                    root_acc,
                    bodies):
    """
    Place roots and spheres with the head and give their velocities and accelerations.

    A point at r from the head origin moves with v + w x r and accelerates with
    a + alpha x r + w x (w x r) (the inertial force of thesis eq. 5 uses the roots').
    """
    R, p, v, a, w, alpha = head.R, head.p, head.v, head.a, head.w, head.alpha
    spheres, sphere_vel = bodies.spheres, bodies.sphere_vel
    for s in range(root_head.shape[0]):
        rx, ry, rz = rotate(R, root_head[s, 0], root_head[s, 1], root_head[s, 2])
        roots[s, 0], roots[s, 1], roots[s, 2] = rx + p[0], ry + p[1], rz + p[2]
        cx = w[1] * rz - w[2] * ry
        cy = w[2] * rx - w[0] * rz
        cz = w[0] * ry - w[1] * rx
        root_vel[s, 0], root_vel[s, 1], root_vel[s, 2] = v[0] + cx, v[1] + cy, v[2] + cz
        root_acc[s, 0] = a[0] + alpha[1] * rz - alpha[2] * ry + w[1] * cz - w[2] * cy
        root_acc[s, 1] = a[1] + alpha[2] * rx - alpha[0] * rz + w[2] * cx - w[0] * cz
        root_acc[s, 2] = a[2] + alpha[0] * ry - alpha[1] * rx + w[0] * cy - w[1] * cx
    for k in range(spheres_head.shape[0]):
        rx, ry, rz = rotate(R, spheres_head[k, 0], spheres_head[k, 1], spheres_head[k, 2])
        spheres[k, 0], spheres[k, 1], spheres[k, 2] = rx + p[0], ry + p[1], rz + p[2]
        spheres[k, 3] = spheres_head[k, 3]
        sphere_vel[k, 0] = v[0] + w[1] * rz - w[2] * ry
        sphere_vel[k, 1] = v[1] + w[2] * rx - w[0] * rz
        sphere_vel[k, 2] = v[2] + w[0] * ry - w[1] * rx


@njit_without_refcounts
def strand_sphere_masks(root, reach, spheres, masks):
    """Broad phase: bit k of masks[s] is set when sphere k can touch strand s."""
    n_s = root.shape[0]
    n_k = spheres.shape[0]
    checked = 0
    for s in range(n_s):
        m = 0
        for k in range(n_k):
            dx = root[s, 0] - spheres[k, 0]
            dy = root[s, 1] - spheres[k, 1]
            dz = root[s, 2] - spheres[k, 2]
            lim = reach[s] + spheres[k, 3]
            checked += 1
            if dx * dx + dy * dy + dz * dz < lim * lim:
                m |= np.int64(1) << np.int64(k)
        masks[s] = m
    return checked


@njit_without_refcounts
def keep_strands_clear_of_spheres(pos, spheres, clearance, which):
    """
    Clear which[s] (in place) where a vertex of strand s is within clearance of a sphere.

    The root is not looked at: it sits on the scalp, held by the head, and takes no contact.
    """
    for s in range(pos.shape[0]):
        if not which[s]:
            continue
        for v in range(1, pos.shape[1]):
            for k in range(spheres.shape[0]):
                dx = pos[s, v, 0] - spheres[k, 0]
                dy = pos[s, v, 1] - spheres[k, 1]
                dz = pos[s, v, 2] - spheres[k, 2]
                lim = spheres[k, 3] + clearance
                if dx * dx + dy * dy + dz * dz <= lim * lim:
                    which[s] = False
            if not which[s]:
                break


@njit_without_refcounts
def place_with_head(head, attach, bodies, collisions, broad_phase):
    """
    Place the roots and spheres with the head, and run the broad phase; return its checks.

    With collisions, masks[s] says which spheres strand s can touch (every sphere without
    the broad phase); a step's substeps share them (the head's motion is the step's).
    """
    root_kinematics(head, attach.root_head, attach.spheres_head, attach.roots,
                    attach.root_vel, attach.root_acc, bodies)
    if not collisions:
        return 0
    if broad_phase:
        return strand_sphere_masks(attach.roots, attach.reach, bodies.spheres, bodies.masks)
    bodies.masks[:] = (np.int64(1) << np.int64(bodies.spheres.shape[0])) - 1
    return 0


@njit_without_refcounts
def _winds_at_middles(pos, t, wind, out, moving=None, strand_t=None):
    """
    Write the wind velocity at each strand's middle vertex into out[s, 0].

    It is the mean plus the seeded turbulence modes, amplitude sin(k . x - w t + phase)
    along each mode's direction. Each mode's phase at t is reduced modulo 2 pi once, so
    that the argument stays a few radians whatever the time; at each strand the modes'
    sines are one loop over the modes with sin_vectorizable (vectorised: libm's sine is
    not, and it was half of this kernel's time with gusts), summed after. With strand_t
    (n_strands,), strand s's time is strand_t[s] (the phases are worked out again where it
    changes from one strand to the next); a strand whose moving[s] is 0 is skipped.
    """
    base = wind.velocity
    amp = wind.amplitude
    mdir, k, mw, mph = wind.mode_dir, wind.mode_k_by_axis, wind.mode_w, wind.mode_phase
    phase, gust = wind.scratch[0], wind.scratch[1]
    n_modes = mw.shape[0]
    phase_t = np.nan                             # the time the phases are of (none yet)
    mid_v = pos.shape[1] // 2
    for s in range(pos.shape[0]):
        if moving is not None and moving[s] <= 0.0:
            continue
        wx, wy, wz = base[0], base[1], base[2]
        if amp <= 0.0:                           # a steady wind
            out[s, 0, 0], out[s, 0, 1], out[s, 0, 2] = wx, wy, wz
            continue
        ts = t
        if strand_t is not None:
            ts = strand_t[s]
        if ts != phase_t:
            for m in range(n_modes):
                phase[m] = mph[m] - np.fmod(mw[m] * ts, 2.0 * pi)
            phase_t = ts
        x, y, z = pos[s, mid_v, 0], pos[s, mid_v, 1], pos[s, mid_v, 2]
        for m in range(n_modes):
            gust[m] = amp * sin_vectorizable(k[0, m] * x + k[1, m] * y + k[2, m] * z + phase[m])
        for m in range(n_modes):
            wx += gust[m] * mdir[m, 0]
            wy += gust[m] * mdir[m, 1]
            wz += gust[m] * mdir[m, 2]
        out[s, 0, 0] = wx
        out[s, 0, 1] = wy
        out[s, 0, 2] = wz


@njit_without_refcounts
def external_forces(strands,
                    root_acc,
                    gravity,
                    wind,
                    wind_on,
                    t,
                    drag_factor,
                    air_damping,
                    root_inertia,
                    forces,
                    multirate=None):
    """
    Set the distributed force of every segment (eq. 5) and clear the end forces.

    F = rho d (g + a) + d f: gravity; with root_inertia, the inertial force -m a of the
    root's acceleration (a model that moves each segment about a root taken as fixed needs
    it; an articulated chain gets the base motion from its dynamics and does not); the
    wind drag 0.5 rho_air Cd width l |v_perp| v_perp on the segment's velocity relative to
    the wind; and air damping -nu m v at the segment's centre, relative to still air. The
    gusts' wavelengths (0.5 - 3 m) are longer than a strand, so the turbulence is evaluated
    once per strand, at its middle vertex.

    multirate, if given, is (steps, times) when strands take substeps of their own
    lengths (the articulated model): each strand's step, 0 where it waits (its forces are
    then left as they are), and the end of its own substep, its time for the wind instead
    of t (or None: t).
    """
    pos, vel, length, mass = strands.pos, strands.vel, strands.length, strands.mass
    f_dist, f_end = forces.f_dist, forces.f_end
    n_s, n_seg = mass.shape
    if wind_on:                  # each strand's wind, held in f_end[s, 0] until cleared
        if multirate is None:
            _winds_at_middles(pos, t, wind, f_end)
        else:
            _winds_at_middles(pos, t, wind, f_end, multirate[0], multirate[1])
    for s in range(n_s):
        if multirate is not None and multirate[0][s] <= 0.0:
            continue
        ax, ay, az = gravity[0], gravity[1], gravity[2]
        if root_inertia:
            ax -= root_acc[s, 0]
            ay -= root_acc[s, 1]
            az -= root_acc[s, 2]
        wx = wy = wz = 0.0
        if wind_on:
            wx, wy, wz = f_end[s, 0, 0], f_end[s, 0, 1], f_end[s, 0, 2]
        for i in range(n_seg):
            m = mass[s, i]
            fx, fy, fz = m * ax, m * ay, m * az
            if wind_on or air_damping > 0.0:
                vx = 0.5 * (vel[s, i, 0] + vel[s, i + 1, 0])
                vy = 0.5 * (vel[s, i, 1] + vel[s, i + 1, 1])
                vz = 0.5 * (vel[s, i, 2] + vel[s, i + 1, 2])
                if air_damping > 0.0:
                    fx -= air_damping * m * vx
                    fy -= air_damping * m * vy
                    fz -= air_damping * m * vz
                if wind_on:
                    seg_len = length[s, i]
                    rx, ry, rz = wx - vx, wy - vy, wz - vz
                    inv_len = 1.0 / seg_len
                    dx = (pos[s, i + 1, 0] - pos[s, i, 0]) * inv_len
                    dy = (pos[s, i + 1, 1] - pos[s, i, 1]) * inv_len
                    dz = (pos[s, i + 1, 2] - pos[s, i, 2]) * inv_len
                    dot = rx * dx + ry * dy + rz * dz
                    rx -= dot * dx
                    ry -= dot * dy
                    rz -= dot * dz
                    q = drag_factor * seg_len * sqrt(rx * rx + ry * ry + rz * rz)
                    fx += q * rx
                    fy += q * ry
                    fz += q * rz
            f_dist[s, i, 0] = fx
            f_dist[s, i, 1] = fy
            f_dist[s, i, 2] = fz
            f_end[s, i, 0] = 0.0
            f_end[s, i, 1] = 0.0
            f_end[s, i, 2] = 0.0


@njit_without_refcounts
def _remove_inward(f, nx, ny, nz, w):
    """
    Eq. 7: drop the fraction w of the component of force f (in place) along -N.

    Returns the force dropped (N, >= 0): what the surface bears of f.
    """
    d = f[0] * nx + f[1] * ny + f[2] * nz
    if d < 0.0:
        f[0] -= w * d * nx
        f[1] -= w * d * ny
        f[2] -= w * d * nz
        return -w * d
    return 0.0


@njit_without_refcounts
def hinge_end_force(s, i, length, hinge):
    """
    Return the force at segment i's end (world) with which its hinge presses it (eq. 3).

    hinge is the thesis model's (chart, theta, phi, trig, rest directions (head frame),
    hinge stiffness, the head's rotation R, theta_prev, phi_prev, inverse inertia,
    hold), its state where the step starts; hold is (w_now, w_prev, c) of the model's
    update (anjyo.hold_weights). The load is what an external moment must take for the
    step to leave the segment where it is: the spring as that update takes it,
    -k (w_now x + w_prev x-), and the motion it carries into the step, c I (x - x-), x
    and x- the deviations from the rest direction's angles now and a step ago in the
    segment's chart. (Eq. 3's -k x alone is that load at rest only. Right after the guard
    stopped a stiff segment, its previous angle sits past the rest angle
    (anjyo._stopped_keep): there the implicit update's spring pulls with about 0.4 k x,
    and a surface that bore k x threw the segment off it by 1.5 times x, every other step:
    bob_fringe's fringe at 1/60 s, 1 mm a step for ever.) A force F at the end has the
    moments l F_theta and l sin(theta) F_phi (eq. 4), so F = (m_theta e_theta + m_phi /
    sin(theta) e_phi) / l. (The step re-centres a chart first where the segment is within
    45 degrees of a pole, and its spring then acts in the new chart; the thesis model
    keeps its segments away from the poles, so that is rare.)
    """
    chart, theta, phi, trig, rest_dir, k_hinge, R, theta_prev, phi_prev, inv_i, hold = hinge
    w_now, w_prev, c_move = hold
    rx, ry, rz = rotate(R, rest_dir[s, i, 0], rest_dir[s, i, 1], rest_dir[s, i, 2])
    # the chart's rows: x, y and the polar axis z
    x0, x1, x2 = chart[s, i, 0, 0], chart[s, i, 0, 1], chart[s, i, 0, 2]
    y0, y1, y2 = chart[s, i, 1, 0], chart[s, i, 1, 1], chart[s, i, 1, 2]
    z0, z1, z2 = chart[s, i, 2, 0], chart[s, i, 2, 1], chart[s, i, 2, 2]
    th0 = acos(min(1.0, max(-1.0, z0 * rx + z1 * ry + z2 * rz)))
    x_th = theta[s, i] - th0
    x_ph = phi[s, i] - atan2(y0 * rx + y1 * ry + y2 * rz, x0 * rx + x1 * ry + x2 * rz)
    x_ph = wrap_angle(x_ph)
    turn_ph = wrap_angle(phi[s, i] - phi_prev[s, i])
    k = k_hinge[s, i]
    moving = c_move / inv_i[s, i]
    turn_th = theta[s, i] - theta_prev[s, i]
    m_th = -k * (w_now * x_th + w_prev * (x_th - turn_th)) + moving * turn_th
    m_ph = -k * (w_now * x_ph + w_prev * (x_ph - turn_ph)) + moving * turn_ph
    st, ct, sp, cp = trig[s, i, 0], trig[s, i, 1], trig[s, i, 2], trig[s, i, 3]
    f_th = m_th / length[s, i]
    f_ph = m_ph / (length[s, i] * max(st, 1e-3))
    # along e_theta and e_phi (fig. 4.3, as anjyo._moments_of_trig)
    a, b, c = f_th * ct * cp - f_ph * sp, f_th * ct * sp + f_ph * cp, -f_th * st
    return a * x0 + b * y0 + c * z0, a * x1 + b * y1 + c * z1, a * x2 + b * y2 + c * z2


@njit_without_refcounts
def _contact_weight(d, r):
    """
    Return how much in contact a point at distance d from a centre is.

    1 up to GUARD_MARGIN outside (the guard leaves vertices GUARD_LIFT out, well within
    it), 0 past the skin, linear between: an on/off switch would chatter at the skin's
    edge.
    """
    return min(1.0, max(0.0, (r + CONTACT_SKIN - d) / (CONTACT_SKIN - GUARD_MARGIN)))


@njit_without_refcounts
def _record_contact(contact, s, i, k, c, normal, lever, sphere, load):
    """
    Record a contact of segment i for an implicit model.

    Its stiffness, damping, normal, lever, sphere, and load: the normal force the surface
    bears, (at the point, at the segment's middle); eq. 7 drops a vertex's inward
    distributed force, which acts at the middle.

    Into a free slot, or else over the slot with the weakest contact if this one is stiffer.
    """
    nx, ny, nz = normal
    weakest = 0
    least = np.inf
    for q in range(CONTACT_SLOTS):
        slot = q * CONTACT_FIELDS
        held = contact[s, i, slot + CONTACT_K] + contact[s, i, slot + CONTACT_C]
        if held < least:
            least = held
            weakest = q
        if held == 0.0:
            break
    if k + c > least:
        slot = weakest * CONTACT_FIELDS
        contact[s, i, slot + CONTACT_K] = k
        contact[s, i, slot + CONTACT_C] = c
        contact[s, i, slot + CONTACT_NX] = nx
        contact[s, i, slot + CONTACT_NY] = ny
        contact[s, i, slot + CONTACT_NZ] = nz
        contact[s, i, slot + CONTACT_LEVER] = lever
        contact[s, i, slot + CONTACT_SPHERE] = sphere
        contact[s, i, slot + CONTACT_LOAD] = load[0]
        contact[s, i, slot + CONTACT_LOAD_MID] = load[1]


@njit_without_refcounts
def clear_contact_record(contact, moving=None):
    """
    Clear the contact record: no slot of any segment holds a contact (stiffness, damping 0).

    moving (n_strands,), if given, is each strand's step: a strand whose step is 0 waits
    and keeps its record.
    """
    for s in range(contact.shape[0]):
        if moving is not None and moving[s] <= 0.0:
            continue
        for i in range(contact.shape[1]):
            for q in range(CONTACT_SLOTS):
                contact[s, i, q * CONTACT_FIELDS + CONTACT_K] = 0.0
                contact[s, i, q * CONTACT_FIELDS + CONTACT_C] = 0.0


@njit_without_refcounts
def reaction_constraint_forces(strands,
                               bodies,
                               k_per_m,
                               c_per_m,
                               record_contacts,
                               forces,
                               hinge=None,
                               moving=None,
                               drop_input=True,
                               force_at_q=False):
    """
    Collision response by reaction constraints (eqs. 7-10) for vertices and segments.

    A vertex P in contact (inside, or within CONTACT_SKIN outside) keeps only the outward
    part of its input force (eq. 7) and gets F_constrained = -(k PT + c V.N) N (eq. 8), PT
    the signed distance from the nearest surface point T along the outward normal N (only
    its inward part pushes) and V the velocity relative to the sphere. k and c are given
    per metre of strand and scaled by the segment's length, like its mass.
    A segment whose inner point Q is inside (both ends outside) gets the same response at Q
    with the input force interpolated from its ends, moved to the free end with weight t so
    that the torque about the segment's start is the same; a segment whose start already
    touches the sphere (a root on the scalp) is left to that vertex's own test. Returns
    the contacts found.

    force_at_q is for a model whose segments pass a force on to their parents (the
    articulated chain): eq. 10's response then acts at Q as it is, split between the
    segment's centre and its end so that both the force and its moment are those at Q.
    Moved to the end with weight t, the chain's parents felt only t of it: the rest, (1 -
    t) of the response, pulled the segment's start into the sphere, unopposed by the
    contact's implicit damping (which holds Q), so the rod pivoted about Q and its ends
    were flung (hanging scene, 50 x 10 strands at 1/60 s with collision_damping 0.3: a
    strand gained 0.39 m g L of energy in one step; 0.002 at most with the force at Q).

    With record_contacts each contact is also written to forces.contact (cleared first),
    for a model that takes contacts implicitly; a model that does not read the record
    passes False and the kernel leaves it alone (clearing it touched every cache line of a
    record nine times the size of the forces, each step).

    hinge (as hinge_end_force takes it) is for a model whose hinge springs are not among
    the input forces (the thesis model's eq. 3 acts in its angular update; that model adds
    the springs of 5.2 to the input forces before this call): the surface then bears only
    what the input forces and the hinge spring press on it with together, and eq. 7 puts
    back what it dropped beyond that. Eq. 7 alone dropped gravity's inward part while the
    spring, turned against gravity to hold the style (gravity compensation), went on
    lifting: a segment resting within CONTACT_SKIN of the scalp was thrown off it, fell
    back, and did so for ever at 1/60 s (side_swept_long released at rest under a head
    tilted by 0.25 rad: a cycle of three steps, 1.5 mm at the first vertex).

    moving (n_strands,), if given, is each strand's step: a strand whose step is 0 waits
    and is left as it is (forces and record).

    drop_input False is for a model that makes the surface bear what presses on it by its
    own contact impulses (the articulated chain: ArticulatedSolver.drops_inward_input):
    no share of the input force is dropped (eq. 7, and eq. 10's at Q), only eq. 8's
    penalty and damping are added, and the load recorded is the penalty's. The share
    eq. 7 drops is ramped over CONTACT_SKIN by distance, and for the chain it did not
    count the joint springs (they are not input forces): a strand hanging with its tip
    inside the skin had part of gravity's pull dropped while its sag-free springs went
    on lifting, and swung 0.6-1.1 mm for ever (thesis_long after violent motion).
    """
    pos, vel, length = strands.pos, strands.vel, strands.length
    spheres, sphere_vel, masks = bodies.spheres, bodies.sphere_vel, bodies.masks
    f_dist, f_end, contact = forces.f_dist, forces.f_end, forces.contact
    n_s, n_seg = f_dist.shape[0], f_dist.shape[1]
    contacts = 0
    if record_contacts:
        clear_contact_record(contact, moving)
    for s in range(n_s):
        if moving is not None and moving[s] <= 0.0:
            continue
        mask = masks[s]
        if mask == 0:
            continue
        for kk in range(spheres.shape[0]):
            if not (mask >> np.int64(kk)) & np.int64(1):
                continue
            cx, cy, cz, r = spheres[kk, 0], spheres[kk, 1], spheres[kk, 2], spheres[kk, 3]
            for i in range(n_seg):
                px, py, pz = pos[s, i + 1, 0], pos[s, i + 1, 1], pos[s, i + 1, 2]
                ex, ey, ez = px - cx, py - cy, pz - cz
                d2 = ex * ex + ey * ey + ez * ez
                reach = r + CONTACT_SKIN + length[s, i]
                if d2 > reach * reach:
                    continue        # neither the end nor any point of the segment is in contact
                k = k_per_m * length[s, i]
                c = c_per_m * length[s, i]
                d = sqrt(d2)
                if d < r + CONTACT_SKIN and d > 1e-12:
                    nx, ny, nz = ex / d, ey / d, ez / d
                    vx = vel[s, i + 1, 0] - sphere_vel[kk, 0]
                    vy = vel[s, i + 1, 1] - sphere_vel[kk, 1]
                    vz = vel[s, i + 1, 2] - sphere_vel[kk, 2]
                    w = _contact_weight(d, r)
                    if hinge is not None:
                        # what presses on the surface, as a force at the end: the input
                        # forces' moments about the start, and the spring's
                        sx, sy, sz = hinge_end_force(s, i, length, hinge)
                        pressing = -min(0.0, (0.5 * f_dist[s, i, 0] + f_end[s, i, 0] + sx) * nx
                                        + (0.5 * f_dist[s, i, 1] + f_end[s, i, 1] + sy) * ny
                                        + (0.5 * f_dist[s, i, 2] + f_end[s, i, 2] + sz) * nz)
                    load_mid = load = 0.0
                    if drop_input:
                        load_mid = _remove_inward(f_dist[s, i], nx, ny, nz, w)
                        load = _remove_inward(f_end[s, i], nx, ny, nz, w)
                    load += k * max(r - d, 0.0)
                    if hinge is not None:
                        # eq. 7 bears at most that: the rest of what it dropped is put back
                        excess = 0.5 * load_mid + load - k * max(r - d, 0.0) - pressing
                        if excess > 0.0:
                            f_end[s, i, 0] -= excess * nx
                            f_end[s, i, 1] -= excess * ny
                            f_end[s, i, 2] -= excess * nz
                    mag = k * max(r - d, 0.0) - w * c * (vx * nx + vy * ny + vz * nz)  # eq. 8
                    f_end[s, i, 0] += mag * nx
                    f_end[s, i, 1] += mag * ny
                    f_end[s, i, 2] += mag * nz
                    if record_contacts:
                        _record_contact(contact, s, i, k if d < r else 0.0, w * c,
                                        (nx, ny, nz), 1.0, kk, (load, load_mid))
                    contacts += 1
                    continue
                ax, ay, az = pos[s, i, 0], pos[s, i, 1], pos[s, i, 2]
                ox, oy, oz = ax - cx, ay - cy, az - cz
                if ox * ox + oy * oy + oz * oz < (r + CONTACT_SKIN) ** 2:
                    continue        # the start touches this sphere: its own vertex test rules
                sx, sy, sz = px - ax, py - ay, pz - az
                ll = sx * sx + sy * sy + sz * sz
                tt = ((cx - ax) * sx + (cy - ay) * sy + (cz - az) * sz) / ll
                if tt <= 0.0 or tt >= 1.0:
                    continue
                qx, qy, qz = ax + tt * sx - cx, ay + tt * sy - cy, az + tt * sz - cz
                dq = sqrt(qx * qx + qy * qy + qz * qz)
                if dq >= r + CONTACT_SKIN or dq < 1e-12:
                    continue
                nx, ny, nz = qx / dq, qy / dq, qz / dq
                # fn: the input force at Q, interpolated between the segment's two ends,
                # along N (summed in place of a 3-vector: nothing is allocated per contact)
                fn = 0.0
                for a in range(3):
                    f1 = f_dist[s, i, a] + f_end[s, i, a]
                    f0 = 0.0 if i == 0 else f_dist[s, i - 1, a] + f_end[s, i - 1, a]
                    n_a = nx if a == 0 else (ny if a == 1 else nz)
                    fn += ((1.0 - tt) * f0 + tt * f1) * n_a
                vx = (1 - tt) * vel[s, i, 0] + tt * vel[s, i + 1, 0] - sphere_vel[kk, 0]
                vy = (1 - tt) * vel[s, i, 1] + tt * vel[s, i + 1, 1] - sphere_vel[kk, 1]
                vz = (1 - tt) * vel[s, i, 2] + tt * vel[s, i + 1, 2] - sphere_vel[kk, 2]
                w = _contact_weight(dq, r)
                borne = -w * min(fn, 0.0) if drop_input else 0.0
                if hinge is not None:
                    # at most what presses this segment on Q (see above): its own loads'
                    # moment about its start (eq. 4: the distributed force at half its
                    # length, the end force and the hinge spring, as forces at the end) over
                    # Q's lever tt. (fn also holds the previous segment's forces, which turn
                    # that segment and not this one: bearing them too threw the tips of
                    # side_swept_long and bob_fringe off the head and back every step)
                    sx, sy, sz = hinge_end_force(s, i, length, hinge)
                    own = ((0.5 * f_dist[s, i, 0] + f_end[s, i, 0] + sx) * nx
                           + (0.5 * f_dist[s, i, 1] + f_end[s, i, 1] + sy) * ny
                           + (0.5 * f_dist[s, i, 2] + f_end[s, i, 2] + sz) * nz)
                    borne = min(borne, max(0.0, -own / tt))
                mag = borne + k * max(r - dq, 0.0) - w * c * (
                    vx * nx + vy * ny + vz * nz)                               # eq. 10
                if force_at_q:
                    # at the centre a and the end b: a + b = 1, (a / 2 + b) = tt of the
                    # force's moment about the start
                    at_mid = 2.0 * (1.0 - tt) * mag
                    f_dist[s, i, 0] += at_mid * nx
                    f_dist[s, i, 1] += at_mid * ny
                    f_dist[s, i, 2] += at_mid * nz
                    mag *= 2.0 * tt - 1.0
                else:
                    mag *= tt
                f_end[s, i, 0] += mag * nx
                f_end[s, i, 1] += mag * ny
                f_end[s, i, 2] += mag * nz
                if record_contacts:
                    load = max(0.0, borne + k * max(r - dq, 0.0))
                    _record_contact(contact, s, i, k if dq < r else 0.0, w * c, (nx, ny, nz),
                                    tt, kk, (load, 0.0))
                contacts += 1
    return contacts


@njit_without_refcounts
def _wall_sd(pos, px, py, pz, a, b, j):
    """wall_signed_distance with Q's scalp projection (px, py, pz) given."""
    n_v = pos.shape[1]
    qx, qy, qz = pos[b, j, 0], pos[b, j, 1], pos[b, j, 2]
    j0 = max(j - 1, 0)
    j1 = min(j + 1, n_v - 1)
    tx = pos[b, j1, 0] - pos[b, j0, 0]
    ty = pos[b, j1, 1] - pos[b, j0, 1]
    tz = pos[b, j1, 2] - pos[b, j0, 2]
    wx, wy, wz = px - qx, py - qy, pz - qz
    nx, ny, nz = ty * wz - tz * wy, tz * wx - tx * wz, tx * wy - ty * wx
    n = sqrt(nx * nx + ny * ny + nz * nz)
    if n < 1e-15:
        return 1e30, 0.0, 0.0, 0.0, 0.0
    nx /= n
    ny /= n
    nz /= n
    rx, ry, rz = pos[a, j, 0] - qx, pos[a, j, 1] - qy, pos[a, j, 2] - qz
    ww = wx * wx + wy * wy + wz * wz
    along = (rx * wx + ry * wy + rz * wz) / ww if ww > 1e-18 else 0.0
    return rx * nx + ry * ny + rz * nz, nx, ny, nz, along


@njit_without_refcounts
def wall_signed_distance(pos, scalp, a, b, j):
    """
    Signed distance of vertex j of strand a from strand b's projected wall (thesis 5.2).

    The wall is the polygon from b's vertex Q down to its scalp projection Q', locally the
    plane through Q spanned by b's tangent and QQ'. Returns (distance, nx, ny, nz, along)
    with the unit normal and the position of a's vertex along QQ' (0 at Q, 1 at Q').
    """
    px, py, pz = nearest_on_spheres(pos[b, j, 0], pos[b, j, 1], pos[b, j, 2], scalp)
    return _wall_sd(pos, px, py, pz, a, b, j)


@njit_without_refcounts
def strip_springs(strands,
                  scalp,
                  springs,
                  constants,
                  forces):
    """
    Springs of thesis 5.2, eq. 11 (F = -k x), added to the end forces of the segments.

    Type 1 joins vertex j of facing strands of neighbouring strips; type 2 is inserted only
    when a vertex comes within d2 of its neighbour's projected wall and pushes it back to
    d2 (from at most WALL_PUSH_CAP d2 short of it); type 3 joins a vertex to its own scalp
    projection (rest3 < 0 disables it). The constants are per metre of strand, scaled by
    the length of the segment each vertex ends.
    Returns the number of type-2 springs inserted. proj is scratch space (n_strands,
    n_vertices, 3) for every vertex's scalp projection, computed once and shared.
    """
    pos, length = strands.pos, strands.length
    pairs, rest1, wall_sign = springs.pairs, springs.rest1, springs.wall_sign
    wall_rest = springs.wall_rest
    rest3, proj = springs.rest3, springs.proj
    k1, k2, d2, k3 = constants.neighbor, constants.wall, constants.wall_distance, constants.scalp
    f_end = forces.f_end
    n_v = pos.shape[1]
    inserted = 0
    for s in range(pos.shape[0]):
        for j in range(1, n_v):
            px, py, pz = nearest_on_spheres(pos[s, j, 0], pos[s, j, 1], pos[s, j, 2], scalp)
            proj[s, j, 0], proj[s, j, 1], proj[s, j, 2] = px, py, pz
    for q in range(pairs.shape[0]):
        a, b = pairs[q, 0], pairs[q, 1]
        for j in range(1, n_v):
            if k1 > 0.0:
                dx = pos[b, j, 0] - pos[a, j, 0]
                dy = pos[b, j, 1] - pos[a, j, 1]
                dz = pos[b, j, 2] - pos[a, j, 2]
                d = sqrt(dx * dx + dy * dy + dz * dz)
                if d > 1e-12:
                    f = 0.5 * k1 * (length[a, j - 1] + length[b, j - 1]) * (d - rest1[q, j]) / d
                    f_end[a, j - 1, 0] += f * dx
                    f_end[a, j - 1, 1] += f * dy
                    f_end[a, j - 1, 2] += f * dz
                    f_end[b, j - 1, 0] -= f * dx
                    f_end[b, j - 1, 1] -= f * dy
                    f_end[b, j - 1, 2] -= f * dz
            if k2 > 0.0:
                for side in range(2):
                    me, other = (a, b) if side == 0 else (b, a)
                    sd, nx, ny, nz, along = _wall_sd(pos, proj[other, j, 0], proj[other, j, 1],
                                                     proj[other, j, 2], me, other, j)
                    sd *= wall_sign[q, j, side]
                    taper = min(1.0,
                                max(0.0, WALL_TAPER_SLOPE * (along + WALL_TAPER_REACH)),
                                max(0.0, WALL_TAPER_SLOPE * (1.0 + WALL_TAPER_REACH - along)))
                    reach = min(d2, wall_rest[q, j, side])
                    if sd < reach and taper > 0.0:
                        push = min(reach - sd, WALL_PUSH_CAP * reach)
                        f = taper * k2 * length[me, j - 1] * push * wall_sign[q, j, side]
                        f_end[me, j - 1, 0] += f * nx
                        f_end[me, j - 1, 1] += f * ny
                        f_end[me, j - 1, 2] += f * nz
                        # reaction on the wall's top vertex Q (the scalp holds Q')
                        g = f * min(1.0, max(0.0, 1.0 - along))
                        f_end[other, j - 1, 0] -= g * nx
                        f_end[other, j - 1, 1] -= g * ny
                        f_end[other, j - 1, 2] -= g * nz
                        inserted += 1
    if k3 > 0.0:
        for s in range(pos.shape[0]):
            for j in range(1, n_v):
                if rest3[s, j] < 0.0:
                    continue
                dx = pos[s, j, 0] - proj[s, j, 0]
                dy = pos[s, j, 1] - proj[s, j, 1]
                dz = pos[s, j, 2] - proj[s, j, 2]
                d = sqrt(dx * dx + dy * dy + dz * dz)
                if d > 1e-12:
                    f = -k3 * length[s, j - 1] * (d - rest3[s, j]) / d
                    f_end[s, j - 1, 0] += f * dx
                    f_end[s, j - 1, 1] += f * dy
                    f_end[s, j - 1, 2] += f * dz
    return inserted


@njit_without_refcounts
def _end_cone(sx, sy, sz, r, seg_len, margin):
    """
    Return (u, kappa) of the cone a segment's end direction must keep out of.

    The end p + l d is margin outside a sphere iff d.u <= kappa. (sx, sy, sz) is the start
    p less the sphere's centre, u the unit vector from p to the centre; kappa <= -1 when
    the end cannot reach the sphere.
    """
    D = sqrt(sx * sx + sy * sy + sz * sz)
    rr = r + margin
    return -sx / D, -sy / D, -sz / D, (D * D + seg_len * seg_len - rr * rr) / (2.0 * seg_len * D)


@njit_without_refcounts
def guard_segment(start, end, seg_len, spheres, mask, margin=GUARD_MARGIN,
                  sag_by_height=False):
    """
    Position guard: turn the segment p->e (length l) so no vertex ends inside a sphere.

    The penalty force of eq. 8 must stay soft for the explicit force term, so a fast
    vertex can still cross a sphere's surface within one step; this moves the end vertex
    radially out to `margin` outside the sphere (both models pass GUARD_LIFT), or the
    segment's deepest point to within its chord allowance (SEGMENT_TOLERANCE, plus the
    sag of a chord resting on the sphere), by turning the segment about its start. The
    sag fades over the contact skin with the start's height (the thesis model), or with
    sag_by_height, mm for mm with the height of the lower end (the articulated
    model: see articulated.SAG_BY_HEIGHT). Spheres that contain the start are left
    alone. Returns the
    new end point and whether anything moved.
    """
    px, py, pz = start
    ex, ey, ez = end
    moved = False
    for sweep in range(2 * GUARD_PASSES):
        # A segment can be caught between two constraints that undo each other: its end
        # out of one sphere, its chord out of another it starts near. Measured (articulated
        # gale): after GUARD_PASSES sweeps a tip was still 0.04 mm inside a scalp sphere.
        # The end outside is the promise and the chord's allowance a tolerance, so when the
        # sweeps have not settled (a sweep that changes nothing ends the loop), the rest
        # move the end alone.
        ends_only = sweep >= GUARD_PASSES
        changed = False
        for kk in range(spheres.shape[0]):
            if not (mask >> np.int64(kk)) & np.int64(1):
                continue
            cx, cy, cz, r = spheres[kk, 0], spheres[kk, 1], spheres[kk, 2], spheres[kk, 3]
            dx, dy, dz = ex - cx, ey - cy, ez - cz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 > (r + seg_len) * (r + seg_len):
                continue            # the end is so far out that no point of the segment is in
            sx, sy, sz = px - cx, py - cy, pz - cz
            if sx * sx + sy * sy + sz * sz < (r - START_INSIDE) * (r - START_INSIDE):
                continue
            tx, ty, tz = 0.0, 0.0, 0.0
            hit = False
            if d2 < r * r:
                # The end p + l d' stays outside iff d'.u <= kappa (_end_cone): project d
                # onto that cone, exactly.
                ux, uy, uz, kappa = _end_cone(sx, sy, sz, r, seg_len, margin)
                if kappa > -1.0:
                    kappa = min(kappa, 1.0)
                    # (heading straight at the centre: any side will do)
                    ox, oy, oz = perpendicular_unit(ex - px, ey - py, ez - pz, ux, uy, uz,
                                                    1e-12)
                    sk = sqrt(max(0.0, 1.0 - kappa * kappa))
                    tx = px + kappa * ux + sk * ox
                    ty = py + kappa * uy + sk * oy
                    tz = pz + kappa * uz + sk * oz
                    hit = True
            elif not ends_only:
                # A segment whose start rests on the surface may sag in like a chord lying
                # on the sphere (at most l^2 / 8r); one whose start is clear of the skin
                # may dip SEGMENT_TOLERANCE. The allowance is continuous in the start's
                # height and the guard stops exactly at it, so a resting segment reaches a
                # fixed point instead of flickering across a threshold. Only a segment
                # whose nearest inner point is inside the sphere can be too deep: the
                # square roots come after that test.
                ux, uy, uz = ex - px, ey - py, ez - pz
                tt = -(sx * ux + sy * uy + sz * uz) / (seg_len * seg_len)
                if 0.0 < tt < 1.0:
                    qx, qy, qz = sx + tt * ux, sy + tt * uy, sz + tt * uz
                    dq2 = qx * qx + qy * qy + qz * qz
                    if dq2 >= r * r:
                        continue
                    dq = sqrt(dq2)
                    ds = sqrt(sx * sx + sy * sy + sz * sz)
                    sag = seg_len * seg_len / (8.0 * r)
                    if sag_by_height:
                        # the sag of a chord whose lower end is that high: a chain
                        # resting on the sphere (both ends within the sag) is left alone
                        low = min(ds, sqrt(d2)) - r
                        allow = SEGMENT_TOLERANCE + max(0.0, sag - max(low, 0.0))
                    else:
                        allow = SEGMENT_TOLERANCE + sag * min(
                            1.0, max(0.0, (r + CONTACT_SKIN - ds) / CONTACT_SKIN))
                    if dq < r - allow:
                        f = (r - allow + 1e-6) / max(dq, 1e-12)
                        # where the segment's point at tt must go, seen from p
                        tx = px + (cx + f * qx - px) / tt
                        ty = py + (cy + f * qy - py) / tt
                        tz = pz + (cz + f * qz - pz) / tt
                        hit = True
            if hit:
                ux, uy, uz = tx - px, ty - py, tz - pz
                n = sqrt(ux * ux + uy * uy + uz * uz)
                if n > 1e-12:
                    inv = seg_len / n
                    ex, ey, ez = px + inv * ux, py + inv * uy, pz + inv * uz
                    moved = True
                    changed = True
        if not changed:
            break
    if changed:
        # Still not settled: the end is caught in a crease, each sphere's turn putting it
        # back into the other (measured: a tip left 0.28 mm inside one of two spheres after
        # the stress bench's random run, 1/240 s). Solve the crease exactly instead.
        ex, ey, ez = _end_out_of_a_crease((px, py, pz), (ex, ey, ez), seg_len, spheres, mask,
                                          margin)
    return ex, ey, ez, moved


@njit_without_refcounts
def _crease_cone(start, spheres, k, seg_len, margin, mask):
    """
    Return (u, kappa) of sphere k's cone for _end_out_of_a_crease; kappa 2: no constraint.

    Spheres out of the mask, holding the start, or that the end cannot reach constrain
    nothing.
    """
    if not (mask >> np.int64(k)) & np.int64(1):
        return 0.0, 0.0, 0.0, 2.0
    px, py, pz = start
    sx, sy, sz = px - spheres[k, 0], py - spheres[k, 1], pz - spheres[k, 2]
    D = sqrt(sx * sx + sy * sy + sz * sz)
    r = spheres[k, 3]
    if D < r - START_INSIDE or D < 1e-12:
        return 0.0, 0.0, 0.0, 2.0
    ux, uy, uz, kappa = _end_cone(sx, sy, sz, r, seg_len, margin)
    if kappa <= -1.0:
        return 0.0, 0.0, 0.0, 2.0          # the end cannot reach this sphere
    return ux, uy, uz, min(kappa, 1.0)


@njit_without_refcounts
def _outside_every_cone(cx, cy, cz, start, spheres, seg_len, margin, mask):
    """Return whether direction c keeps the end out of every sphere's cone (1e-12 slack)."""
    for k in range(spheres.shape[0]):
        ux, uy, uz, kap = _crease_cone(start, spheres, k, seg_len, margin, mask)
        if kap < 1.5 and cx * ux + cy * uy + cz * uz > kap + 1e-12:
            return False
    return True


@njit_without_refcounts
def _end_out_of_a_crease(start, end, seg_len, spheres, mask, margin):
    """
    Return the end p + l d nearest the given one with d outside every sphere's cone.

    The end stays outside sphere k iff d.u_k <= kappa_k (see guard_segment), so the
    allowed directions are the unit sphere less some caps. The nearest allowed direction
    lies on one cap's rim or where two rims cross: every such candidate is tried and the
    nearest that every cap allows is taken (the end is left alone if none is).
    Spheres that hold the start are left out, as in guard_segment. The cones are worked
    out where they are needed (_crease_cone), not kept: this rare path allocates nothing.
    """
    px, py, pz = start
    ex, ey, ez = end
    n = spheres.shape[0]
    dx, dy, dz = (ex - px) / seg_len, (ey - py) / seg_len, (ez - pz) / seg_len
    if _outside_every_cone(dx, dy, dz, start, spheres, seg_len, margin, mask):
        return ex, ey, ez
    best = -2.0
    bx, by, bz = dx, dy, dz
    for a in range(n):
        uax, uay, uaz, kap_a = _crease_cone(start, spheres, a, seg_len, margin, mask)
        if kap_a > 1.5:
            continue
        for b in range(a, n):
            ubx, uby, ubz, kap_b = _crease_cone(start, spheres, b, seg_len, margin, mask)
            if kap_b > 1.5:
                continue
            for sign in range(2):
                if a == b:
                    if sign == 1:
                        break
                    # the nearest point of cap a's rim
                    ox, oy, oz = perpendicular_unit(dx, dy, dz, uax, uay, uaz, 1e-12)
                    sk = sqrt(max(0.0, 1.0 - kap_a * kap_a))
                    cx = kap_a * uax + sk * ox
                    cy = kap_a * uay + sk * oy
                    cz = kap_a * uaz + sk * oz
                else:
                    # d = al u_a + be u_b + ga (u_a x u_b) on both rims
                    c = uax * ubx + uay * uby + uaz * ubz
                    det = 1.0 - c * c
                    if det < 1e-12:
                        break
                    al = (kap_a - c * kap_b) / det
                    be = (kap_b - c * kap_a) / det
                    wx = al * uax + be * ubx
                    wy = al * uay + be * uby
                    wz = al * uaz + be * ubz
                    rest = 1.0 - (wx * wx + wy * wy + wz * wz)
                    if rest < 0.0:
                        break                      # the rims do not cross
                    nx = uay * ubz - uaz * uby
                    ny = uaz * ubx - uax * ubz
                    nz = uax * uby - uay * ubx
                    ga = sqrt(rest / det) * (1.0 if sign == 0 else -1.0)
                    cx, cy, cz = wx + ga * nx, wy + ga * ny, wz + ga * nz
                near = cx * dx + cy * dy + cz * dz
                if near > best and \
                        _outside_every_cone(cx, cy, cz, start, spheres, seg_len, margin, mask):
                    best = near
                    bx, by, bz = cx, cy, cz
    return px + seg_len * bx, py + seg_len * by, pz + seg_len * bz


@njit_without_refcounts
def guard_rest_shape(rest, spheres):
    """
    Make a rest shape (head frame) consistent with the position guard, in place.

    A modeled strand may have chords that sag a little into the scalp; a hinge spring
    pulling towards such a shape would fight the guard for ever. Each segment, root to tip,
    is turned exactly as the guard would turn it. Returns the number of segments moved.
    """
    n_s, n_v = rest.shape[0], rest.shape[1]
    all_spheres = (np.int64(1) << np.int64(spheres.shape[0])) - np.int64(1)
    moved = 0
    for s in range(n_s):
        for j in range(n_v - 1):
            px, py, pz = rest[s, j, 0], rest[s, j, 1], rest[s, j, 2]
            dx, dy, dz = rest[s, j + 1, 0] - px, rest[s, j + 1, 1] - py, rest[s, j + 1, 2] - pz
            seg_len = sqrt(dx * dx + dy * dy + dz * dz)
            end = (rest[s, j + 1, 0], rest[s, j + 1, 1], rest[s, j + 1, 2])
            ex, ey, ez, m = guard_segment((px, py, pz), end, seg_len, spheres, all_spheres)
            if m:
                # carry the rest of the strand along rigidly so other segments keep theirs
                ox, oy, oz = ex - rest[s, j + 1, 0], ey - rest[s, j + 1, 1], ez - rest[s, j + 1, 2]
                for k in range(j + 1, n_v):
                    rest[s, k, 0] += ox
                    rest[s, k, 1] += oy
                    rest[s, k, 2] += oz
                moved += 1
    return moved


def explicit_stability_problem(omega_squared, air_damping, dt, margin, what):
    """
    Return why explicit terms would be unstable at dt (or None); both models ask this.

    omega_squared: the explicit terms' squared frequencies per segment; air damping acts
    explicitly on every segment. `what` names the model and its explicit terms.
    """
    if air_damping * dt > 2.0 * margin:
        return ('air_damping %g/s needs dt below %.2g s'
                % (air_damping, 2.0 * margin / air_damping))
    omega = float(np.sqrt(np.max(omega_squared)))
    if omega * dt > 2.0 * margin:
        return ('unstable with %s at dt = %.4g s: the stiffest explicit term has omega = '
                '%.0f rad/s, which needs dt below %.3g s'
                % (what, dt, omega, 2.0 * margin / omega))
    return None
