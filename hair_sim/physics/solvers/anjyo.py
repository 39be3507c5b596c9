"""
The thesis model: Anjyo's one-dimensional angular moments (thesis ch. 4, eqs. 1-6).

Every segment i of a strand has a zenith theta and an azimuth phi (thesis fig. 4.3) in a
polar chart of its own: three orthonormal rows (x, y, z) of `chart`, z the polar axis. A
chart is fixed in the world, so the angles carry inertia when the head turns; the rest
direction is rotated into the world with the head every step and the hinge spring
(eq. 3) pulls towards it. Charts are re-centred whenever the segment or its rest
direction comes within 45 degrees of a pole, with both placed on the new equator. Every
step re-centres first, so eqs. 1-6 are always evaluated at least 45 degrees from a pole
(sin(theta) >= 0.707, recorded in stats[MIN_SIN_THETA]). Within a step a segment turns at
most MAX_TURN before the position guard, which may turn it further; whatever angles
result, the next step re-centres before using them.

Each segment carries the sines and cosines of its angles from step to step (`trig`,
advanced by the sums of angles with a series for the step's turn, set afresh after a
re-chart or a guard contact): the moments of eq. 4 and the new direction need no sin or
cos call; only the rest direction's angles are computed every step, by a branch-free
atan2 in a loop LLVM vectorises (libm's acos and atan2 where a chart is re-centred).

Each segment swings about its start as if that were fixed (the root's acceleration enters
as an inertial force), with its own inertia only: cheap, and it holds a style, but it is
not the mechanics of a chain (see solvers/articulated.py).
"""

from collections import namedtuple
from math import acos, atan2, ceil, cos, pi, sin, sqrt

from numba import njit
import numpy as np

from hair_sim.kernels import njit_without_refcounts
from hair_sim.physics.compiled_call import CompiledCall
from hair_sim.physics.forces import (explicit_stability_problem, external_forces, GUARD_LIFT,
                                     GUARD_MOVES, guard_segment, MAX_RATE, MIN_SIN_THETA,
                                     place_with_head, reaction_constraint_forces, RECHARTS,
                                     rotate, strip_springs, TURN_CLAMPS)
from hair_sim.vecmath import atan2_vectorizable, perpendicular_unit, wrap_angle

POLE_COS = cos(pi / 4.0)     # re-chart when |cos(theta)| exceeds this (45 deg from a pole)
MAX_TURN = 0.35              # rad: largest change of theta or phi in one step (guard)
# s: longest substep with collisions and the springs of 5.2 both on. Eqs. 7-10 act
# explicitly, and with those springs they chattered at one step per 60 Hz frame: after
# violent motion 18 of 144 runs at 1/60 s never fell asleep (tips flipping 0.3-9 mm a
# step), every one asleep when carried on at 1/120 s or without collisions; without the
# springs all 144 slept, taken whole (/tmp scripts, 2026-12-02). A longer step is
# taken in equal substeps of at most this (1/60 s: two of 1/120 s); the node's default
# 1/240 s, any step up to 1/120 s, and any step of a scene without contacts or springs
# are taken whole, as before.
CONTACT_SUBSTEP = 1.0 / 120.0
EXPLICIT = 0
IMPLICIT = 1
# Weights of x^{n+1}, x^n, x^{n-1} in the implicit hinge spring. (1/4, 1/2, 1/4) would be
# the trapezoidal rule: no numerical damping, but modes the step cannot resolve (stiff,
# very short segments) then ring for ever at the Nyquist rate. Leaning on x^{n+1} damps
# them (|z| -> sqrt(0.3 / 0.4) per step as omega dt -> infinity) while resolved modes keep
# their period within 1 % up to omega dt ~ 0.35.
W_NEXT, W_NOW, W_PREV = 0.4, 0.3, 0.3

# trig holds (sin theta, cos theta, sin phi, cos phi) of the current angles: a step
# computes them for its new angles anyway, and the next step's eq. 4 needs exactly these
AnjyoState = namedtuple('AnjyoState', ['theta', 'phi', 'theta_prev', 'phi_prev', 'trig',
                                       'chart', 'rest_dir', 'inv_inertia', 'k_hinge',
                                       'packed', 'turned'])
SIN_TH, COS_TH, SIN_PH, COS_PH = 0, 1, 2, 3


@njit_without_refcounts
def _chart_of(chart, s, i):
    """
    Return the chart of segment (s, i) as a tuple of its rows (x, y, z), row by row.

    The step's kernels pass charts as tuples of numbers, not as views of `chart`: a view
    made per segment costs an atomic increment and decrement of the array's reference
    count (numba's runtime), and those were a quarter of a thesis-model step (measured
    with perf: NRT_incref/NRT_decref at 180 strips).
    """
    return (chart[s, i, 0, 0], chart[s, i, 0, 1], chart[s, i, 0, 2],
            chart[s, i, 1, 0], chart[s, i, 1, 1], chart[s, i, 1, 2],
            chart[s, i, 2, 0], chart[s, i, 2, 1], chart[s, i, 2, 2])


@njit_without_refcounts
def _put_chart(chart, s, i, C):
    """Write the chart tuple C (see _chart_of) into chart[s, i]."""
    for r in range(3):
        for c in range(3):
            chart[s, i, r, c] = C[3 * r + c]


@njit_without_refcounts
def _angles(C, dx, dy, dz):
    """Return (theta, phi) of unit direction d in chart C."""
    th, ph, _ = _angles_cos(C, dx, dy, dz)
    return th, ph


@njit_without_refcounts
def _angles_cos(C, dx, dy, dz):
    """Return (theta, phi, cos(theta)) of unit direction d in chart C."""
    cz = C[6] * dx + C[7] * dy + C[8] * dz
    cx = C[0] * dx + C[1] * dy + C[2] * dz
    cy = C[3] * dx + C[4] * dy + C[5] * dz
    cz = min(1.0, max(-1.0, cz))
    return acos(cz), atan2(cy, cx), cz


@njit_without_refcounts
def _direction(C, th, ph):
    """Return the unit direction of angles (theta, phi) in chart C."""
    return _direction_of_trig(C, sin(th), cos(th), sin(ph), cos(ph))


@njit_without_refcounts
def _direction_of_trig(C, st, ct, sp, cp):
    """Return the unit direction in chart C whose angles have these sines and cosines."""
    a = st * cp
    b = st * sp
    return (a * C[0] + b * C[3] + ct * C[6],
            a * C[1] + b * C[4] + ct * C[7],
            a * C[2] + b * C[5] + ct * C[8])


@njit_without_refcounts
def _rechart(C, dx, dy, dz, rx, ry, rz):
    """Return chart C re-centred so that d and the rest direction r lie on its equator."""
    zx = dy * rz - dz * ry
    zy = dz * rx - dx * rz
    zz = dx * ry - dy * rx
    n = sqrt(zx * zx + zy * zy + zz * zz)
    if n < 1e-6:                      # d parallel to r: keep the old polar axis, minimally
        zx, zy, zz = perpendicular_unit(C[6], C[7], C[8], dx, dy, dz, 1e-6)
    else:
        zx /= n
        zy /= n
        zz /= n
    return (dx, dy, dz,
            zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx,
            zx, zy, zz)


@njit_without_refcounts
def _trig_of(th, ph):
    """Return (sin theta, cos theta, sin phi, cos phi) of the angles."""
    return sin(th), cos(th), sin(ph), cos(ph)


@njit_without_refcounts
def _sin_cos_small(d):
    """
    Return (sin d, cos d) for |d| <= MAX_TURN by their Taylor series, to rounding.

    The first omitted terms are d^15 / 15! and d^14 / 14!: below 2e-19 and 5e-18 at 0.35.
    """
    d2 = d * d
    sn = d * (1.0 + d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0 + d2 * (
        1.0 / 362880.0 + d2 * (-1.0 / 39916800.0 + d2 / 6227020800.0))))))
    cs = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0 + d2 * (
        -1.0 / 3628800.0 + d2 / 479001600.0)))))
    return sn, cs


@njit_without_refcounts
def _turn_trig(trig, d_th, d_ph):
    """Return trig (sines and cosines of theta, phi) turned by (d_th, d_ph): sums of angles."""
    sa, ca = _sin_cos_small(d_th)
    sb, cb = _sin_cos_small(d_ph)
    st, ct, sp, cp = trig
    return st * ca + ct * sa, ct * ca - st * sa, sp * cb + cp * sb, cp * cb - sp * sb


@njit_without_refcounts
def init_charts(directions, chart, theta, phi, trig):
    """Set each segment's chart so its direction sits at theta = pi/2, phi = 0."""
    n_s, n_seg = theta.shape
    for s in range(n_s):
        for i in range(n_seg):
            dx, dy, dz = directions[s, i, 0], directions[s, i, 1], directions[s, i, 2]
            C = _rechart((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0), dx, dy, dz, dx, dy, dz)
            _put_chart(chart, s, i, C)
            theta[s, i], phi[s, i] = _angles(C, dx, dy, dz)
            trig[s, i, SIN_TH], trig[s, i, COS_TH], trig[s, i, SIN_PH], trig[s, i, COS_PH] = \
                _trig_of(theta[s, i], phi[s, i])


@njit_without_refcounts
def rotate_charts(chart, R):
    """Rotate every chart by R (a teleport: the hair turns rigidly with the head)."""
    n_s, n_seg = chart.shape[0], chart.shape[1]
    for s in range(n_s):
        for i in range(n_seg):
            for r in range(3):
                x, y, z = chart[s, i, r, 0], chart[s, i, r, 1], chart[s, i, r, 2]
                chart[s, i, r, 0] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
                chart[s, i, r, 1] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
                chart[s, i, r, 2] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z


@njit_without_refcounts
def _recentre(C, th, ph, thp, php, cos_th, rest):
    """
    Re-centre chart C when the segment or its rest direction r nears a pole.

    cos_th is cos(theta) of the segment (the step carries it). Returns (chart, theta, phi,
    previous theta, previous phi, rest theta, rest phi, recharted); rest is (x, y, z).
    """
    rx, ry, rz = rest
    th0, ph0, ct0 = _angles_cos(C, rx, ry, rz)
    if abs(cos_th) > POLE_COS or abs(ct0) > POLE_COS:
        dx, dy, dz = _direction(C, th, ph)
        qx, qy, qz = _direction(C, thp, php)
        C = _rechart(C, dx, dy, dz, rx, ry, rz)
        th, ph = _angles(C, dx, dy, dz)
        thp, php = _angles(C, qx, qy, qz)
        th0, ph0 = _angles(C, rx, ry, rz)
        return C, th, ph, thp, php, th0, ph0, True
    return C, th, ph, thp, php, th0, ph0, False


@njit_without_refcounts
def _moments_of_trig(C, st, ct, sp, cp, seg_len, fd, fe):
    """
    Eq. 4: the moments of the distributed force fd and the end force fe about the start.

    M_theta = u F_theta, M_phi = v F_phi with u = l/2, v = (l/2) sin(theta) for the
    distributed force; forces at the segment's end act with lever l. The angles are given
    by their sines and cosines (the step carries them).
    """
    # unit vectors along increasing theta and phi (fig. 4.3)
    etx = ct * cp * C[0] + ct * sp * C[3] - st * C[6]
    ety = ct * cp * C[1] + ct * sp * C[4] - st * C[7]
    etz = ct * cp * C[2] + ct * sp * C[5] - st * C[8]
    epx = -sp * C[0] + cp * C[3]
    epy = -sp * C[1] + cp * C[4]
    epz = -sp * C[2] + cp * C[5]
    fdt = fd[0] * etx + fd[1] * ety + fd[2] * etz
    fdp = fd[0] * epx + fd[1] * epy + fd[2] * epz
    fet = fe[0] * etx + fe[1] * ety + fe[2] * etz
    fep = fe[0] * epx + fe[1] * epy + fe[2] * epz
    return 0.5 * seg_len * fdt + seg_len * fet, (0.5 * seg_len * fdp + seg_len * fep) * st


@njit_without_refcounts
def _next_deviation(x, xp, moment, k, inv_i, damping, h, integrator):
    """
    Return the next deviation x+ from the rest angle (eq. 3) of one angle.

    explicit: eq. 6 as the thesis writes it (with M/I): x+ = 2x - x- - gamma h (x - x-)
    + h^2 (-k x + M) / I. implicit: the hinge spring at the weighted mean W_NEXT x+ +
    W_NOW x + W_PREV x- and the damping centred, (x+ - x-) / 2h, both implicitly; the
    external moment explicitly. Unconditionally stable for the spring.
    """
    h2 = h * h
    if integrator == EXPLICIT:
        return 2 * x - xp - damping * h * (x - xp) + h2 * inv_i * (-k * x + moment)
    a = k * h2 * inv_i
    b = 0.5 * damping * h
    return (2 * x - xp - a * (W_NOW * x + W_PREV * xp) + b * xp + h2 * inv_i * moment) / (
        1.0 + a * W_NEXT + b)


def _integrator_code(params):
    """Return EXPLICIT or IMPLICIT for params.integrator, as the kernels take it."""
    return EXPLICIT if params.integrator == 'explicit' else IMPLICIT


@njit_without_refcounts
def hold_weights(integrator, damping, h):
    """
    Return (w_now, w_prev, c) of the moment that holds an angle where it is.

    The external moment with which _next_deviation leaves an angle put (x+ = x) is
    M = k (w_now x + w_prev x-) - c I (x - x-).

    explicit: x = 2x - x- - gamma h (x - x-) + h^2 (-k x + M) / I gives (1, 0, (1 - gamma
    h) / h^2); implicit: (W_NEXT + W_NOW, W_PREV, (1 - b) / h^2), b = damping h / 2.
    """
    if integrator == EXPLICIT:
        return 1.0, 0.0, (1.0 - damping * h) / (h * h)
    return W_NEXT + W_NOW, W_PREV, (1.0 - 0.5 * damping * h) / (h * h)


@njit_without_refcounts
def _stopped_keep(a, b):
    """
    Return the share of a stopped segment's deviation its previous angle keeps.

    The guard stops a segment where it turned it out of a sphere. Stopped at deviation x
    from its rest angle, previous = x is at rest for the explicit update; for the implicit
    one it sends the next step to x (1 - (W_NOW + W_PREV) a + b) / (1 + W_NEXT a + b), with
    a = k h^2 / I and b = damping h / 2: -x at a = 10 and -1.5 x as a grows, further past
    the rest angle than the joint was off it, energy that a released spring cannot have.
    a reaches 6.9 at the roots of the long styles at 1/60 s and 2000 in bob_fringe's short
    fringe segments (130 at 1/240 s). With previous = rest + keep x, the next step lands
    at x (1 + b) / (1 + a + b) instead, where backward Euler (L-stable) takes a joint
    released at rest; keep is 1 at a = 0. Measured after 2 s of violent head motion in a
    gale (0, 10, 30 m/s, seeds 1-4): bob_fringe at 1/120 s never slept within 8 s in 4 of
    12 runs, 5 of 12 without this (with GUARD_LIFT and the wall spring's cap), 0 with it.
    """
    back = (1.0 + b) * (1.0 + W_NEXT * a + b) / (1.0 + a + b)
    return (2.0 - W_NOW * a - back) / (1.0 + W_PREV * a - b)


# The turns (the first pass of integrate_strands) run BLOCK segments at a time, from a
# scratch laid out row by row (AnjyoState.packed: one row per input, BLOCK wide) into
# another (AnjyoState.turned), so that the loop over a block is vectorised (four segments
# at a time with AVX2): it has no branch, call or reduction LLVM cannot turn into vector
# code, and its rows sit at constant offsets of two arrays (with runtime row strides, or
# with the state's arrays read directly, LLVM gave up: too many run-time alias checks).
# Measured at 180 strips (3240 segments): the turns 224 -> 69 us a step, plus 26 of packing.
BLOCK = 128
# rows of AnjyoState.packed: the chart (x, y, z rows), the sines and cosines of the
# angles, the rest direction in the world, the distributed and end forces (the inputs
# stored interleaved; those stored one number a segment are read in place)
(PACK_C0, PACK_C1, PACK_C2, PACK_C3, PACK_C4, PACK_C5, PACK_C6, PACK_C7, PACK_C8,
 PACK_SIN_TH, PACK_COS_TH, PACK_SIN_PH, PACK_COS_PH, PACK_RX, PACK_RY, PACK_RZ,
 PACK_FD_X, PACK_FD_Y, PACK_FD_Z, PACK_FE_X, PACK_FE_Y, PACK_FE_Z) = range(22)
PACK_FIELDS = 22
# rows of AnjyoState.turned: the angles before and after the step, the turn of phi, the
# new angles' sines and cosines, the new direction, and 1 where the segment needs the
# exact path instead (_turn_segment_exactly: a re-chart)
(TURN_TH, TURN_NEW_TH, TURN_NEW_PH, TURN_D_PH, TURN_SIN_TH, TURN_COS_TH, TURN_SIN_PH,
 TURN_COS_PH, TURN_DX, TURN_DY, TURN_DZ, TURN_EXACT) = range(12)
TURN_FIELDS = 12
WRAP_ONCE = 3.0 * pi      # one +-2 pi brings an angle difference below this into (-pi, pi]


@njit_without_refcounts
def _pack_segments(interleaved,
                   packed,
                   R,
                   j0,
                   j1):
    """
    Copy the interleaved inputs of segments j0 .. j1 into the rows of `packed`.

    Segments are counted over all strands, root to tip; the inputs are their charts,
    sines and cosines, forces and rest directions: interleaved is (chart, trig, f_dist,
    f_end, rest_dir), each flattened. Field by field, so that each copy is a loop of its
    own; the rest directions are rotated into the world with the head on the way.
    """
    n = j1 - j0
    chart = interleaved[0][9 * j0:9 * j1]
    trig = interleaved[1][4 * j0:4 * j1]
    f_dist = interleaved[2][3 * j0:3 * j1]
    f_end = interleaved[3][3 * j0:3 * j1]
    rest = interleaved[4][3 * j0:3 * j1]
    for c in range(9):
        for j in range(n):
            packed[(PACK_C0 + c) * BLOCK + j] = chart[9 * j + c]
    for c in range(4):
        for j in range(n):
            packed[(PACK_SIN_TH + c) * BLOCK + j] = trig[4 * j + c]
    for c in range(3):
        for j in range(n):
            packed[(PACK_FD_X + c) * BLOCK + j] = f_dist[3 * j + c]
            packed[(PACK_FE_X + c) * BLOCK + j] = f_end[3 * j + c]
    for j in range(n):
        rx, ry, rz = rotate(R, rest[3 * j], rest[3 * j + 1], rest[3 * j + 2])
        packed[PACK_RX * BLOCK + j] = rx
        packed[PACK_RY * BLOCK + j] = ry
        packed[PACK_RZ * BLOCK + j] = rz


@njit_without_refcounts
def _wrap_once(a):
    """wrap_angle for |a| < WRAP_ONCE: one select each way, no loop (vectorisable)."""
    a = a - 2.0 * pi if a > pi else a
    return a + 2.0 * pi if a <= -pi else a


# inlined by numba itself: LLVM left the call in place, and _turn_packed_segments' loop,
# which calls it, was then not vectorised
@njit(cache=True, _nrt=False, error_model='numpy', inline='always')
def _write_turn(turned,
                j,
                angles,
                turn,
                trig,
                C):
    """
    Clamp a segment's turn and write it to slot j of `turned`; return whether it clamped.

    angles (theta, phi) before the step, turn (d_theta, d_phi) of eq. 6, trig their sines
    and cosines before it, C the chart. A turn past MAX_TURN is clamped (guard: counted,
    not hidden); the new sines and cosines come from sums of angles (no sin or cos call:
    |d| <= MAX_TURN), then the new direction.
    """
    th, ph = angles
    d_th, d_ph = turn
    big = (abs(d_th) > MAX_TURN) | (abs(d_ph) > MAX_TURN)
    d_th = min(MAX_TURN, max(-MAX_TURN, d_th)) if big else d_th
    d_ph = min(MAX_TURN, max(-MAX_TURN, d_ph)) if big else d_ph
    nst, nct, nsp, ncp = _turn_trig(trig, d_th, d_ph)
    dx, dy, dz = _direction_of_trig(C, nst, nct, nsp, ncp)
    turned[TURN_TH * BLOCK + j] = th
    turned[TURN_NEW_TH * BLOCK + j] = th + d_th
    turned[TURN_NEW_PH * BLOCK + j] = ph + d_ph
    turned[TURN_D_PH * BLOCK + j] = d_ph
    turned[TURN_SIN_TH * BLOCK + j] = nst
    turned[TURN_COS_TH * BLOCK + j] = nct
    turned[TURN_SIN_PH * BLOCK + j] = nsp
    turned[TURN_COS_PH * BLOCK + j] = ncp
    turned[TURN_DX * BLOCK + j] = dx
    turned[TURN_DY * BLOCK + j] = dy
    turned[TURN_DZ * BLOCK + j] = dz
    return big


@njit_without_refcounts
def _turn_packed_segments(packed,
                          contiguous,
                          turned,
                          damping,
                          h,
                          integrator):
    """
    First pass of integrate_strands over one block: every segment's turn (eqs. 1-6).

    Per segment: the rest angles in its chart, the moments of eq. 4, the update of eq. 6
    (or the implicit variant) and the clamp of the turn, into the rows of `turned`. No
    segment here depends on another (the forces were computed before the step). A segment
    whose chart needs re-centring (it or its rest direction within 45 degrees of a pole)
    is only marked (turned[TURN_EXACT] = 1): _turn_segment_exactly redoes it. contiguous
    is (theta, phi, theta_prev, phi_prev, length, k_hinge, inv_inertia) of the block's
    segments. Returns (clamps among the unmarked, marked).
    """
    theta, phi, theta_prev, phi_prev, length, k_hinge, inv_inertia = contiguous
    clamps = 0
    exact = 0
    for j in range(theta.shape[0]):
        C = (packed[PACK_C0 * BLOCK + j], packed[PACK_C1 * BLOCK + j],
             packed[PACK_C2 * BLOCK + j], packed[PACK_C3 * BLOCK + j],
             packed[PACK_C4 * BLOCK + j], packed[PACK_C5 * BLOCK + j],
             packed[PACK_C6 * BLOCK + j], packed[PACK_C7 * BLOCK + j],
             packed[PACK_C8 * BLOCK + j])
        rx = packed[PACK_RX * BLOCK + j]
        ry = packed[PACK_RY * BLOCK + j]
        rz = packed[PACK_RZ * BLOCK + j]
        # the rest angles (eq. 3): _angles_cos without a call to libm
        cz = C[6] * rx + C[7] * ry + C[8] * rz
        cx = C[0] * rx + C[1] * ry + C[2] * rz
        cy = C[3] * rx + C[4] * ry + C[5] * rz
        cz = min(1.0, max(-1.0, cz))
        th0 = atan2_vectorizable(sqrt((1.0 - cz) * (1.0 + cz)), cz)      # acos(cz)
        ph0 = atan2_vectorizable(cy, cx)
        st = packed[PACK_SIN_TH * BLOCK + j]
        ct = packed[PACK_COS_TH * BLOCK + j]
        sp = packed[PACK_SIN_PH * BLOCK + j]
        cp = packed[PACK_COS_PH * BLOCK + j]
        seg_len = length[j]
        m_th, m_ph = _moments_of_trig(C, st, ct, sp, cp, seg_len,
                                      (packed[PACK_FD_X * BLOCK + j],
                                       packed[PACK_FD_Y * BLOCK + j],
                                       packed[PACK_FD_Z * BLOCK + j]),
                                      (packed[PACK_FE_X * BLOCK + j],
                                       packed[PACK_FE_Y * BLOCK + j],
                                       packed[PACK_FE_Z * BLOCK + j]))
        k = k_hinge[j]
        ii = inv_inertia[j]
        th = theta[j]
        ph = phi[j]
        x_th = th - th0                 # deviations from the rest angles (eq. 3)
        x_thp = theta_prev[j] - th0
        to_rest = ph - ph0
        turn_before = ph - phi_prev[j]
        x_ph = _wrap_once(to_rest)
        x_php = x_ph - _wrap_once(turn_before)
        d_th = _next_deviation(x_th, x_thp, m_th, k, ii, damping, h, integrator) - x_th
        d_ph = _next_deviation(x_ph, x_php, m_ph, k, ii, damping, h, integrator) - x_ph
        near_pole = (abs(ct) > POLE_COS) | (abs(cz) > POLE_COS)
        unwrapped = (abs(to_rest) >= WRAP_ONCE) | (abs(turn_before) >= WRAP_ONCE)
        redo = near_pole | unwrapped
        exact += 1 if redo else 0
        big = _write_turn(turned, j, (th, ph), (d_th, d_ph), (st, ct, sp, cp), C)
        clamps += 1 if big & ~redo else 0
        turned[TURN_EXACT * BLOCK + j] = 1.0 if redo else 0.0
    return clamps, exact


@njit_without_refcounts
def _turn_segment_exactly(state,
                          strands,
                          forces,
                          R,
                          s,
                          i,
                          j,
                          damping,
                          h,
                          integrator):
    """
    Turn segment (s, i), slot j of the block, with its chart re-centred if need be.

    The path for the few segments _turn_packed_segments marks; libm's acos and atan2, and
    wrap_angle's loops. Writes the rows of state.turned and the sine of theta eqs. 1-6 used
    (packed[PACK_SIN_TH]). Returns (re-charted, clamped) as 0 or 1.
    """
    theta, phi, theta_prev, phi_prev = state.theta, state.phi, state.theta_prev, state.phi_prev
    chart, rest_dir, trig, packed = state.chart, state.rest_dir, state.trig, state.packed
    f_dist, f_end = forces.f_dist, forces.f_end
    rx, ry, rz = rotate(R, rest_dir[s, i, 0], rest_dir[s, i, 1], rest_dir[s, i, 2])
    C, th, ph, thp, php, th0, ph0, recharted = _recentre(
        _chart_of(chart, s, i), theta[s, i], phi[s, i], theta_prev[s, i],
        phi_prev[s, i], trig[s, i, COS_TH], (rx, ry, rz))
    if recharted:
        _put_chart(chart, s, i, C)
        tr = _trig_of(th, ph)
    else:
        tr = (trig[s, i, SIN_TH], trig[s, i, COS_TH], trig[s, i, SIN_PH],
              trig[s, i, COS_PH])
    st = tr[SIN_TH]
    seg_len = strands.length[s, i]
    m_th, m_ph = _moments_of_trig(C, st, tr[COS_TH], tr[SIN_PH], tr[COS_PH], seg_len,
                                  (f_dist[s, i, 0], f_dist[s, i, 1], f_dist[s, i, 2]),
                                  (f_end[s, i, 0], f_end[s, i, 1], f_end[s, i, 2]))
    k = state.k_hinge[s, i]
    ii = state.inv_inertia[s, i]
    x_th = th - th0                 # deviations from the rest angles (eq. 3)
    x_thp = thp - th0
    x_ph = wrap_angle(ph - ph0)
    x_php = x_ph - wrap_angle(ph - php)
    d_th = _next_deviation(x_th, x_thp, m_th, k, ii, damping, h, integrator) - x_th
    d_ph = _next_deviation(x_ph, x_php, m_ph, k, ii, damping, h, integrator) - x_ph
    packed[PACK_SIN_TH * BLOCK + j] = st
    clamped = _write_turn(state.turned, j, (th, ph), (d_th, d_ph), tr, C)
    return (1 if recharted else 0), (1 if clamped else 0)


@njit_without_refcounts
def integrate_strands(state,
                      strands,
                      forces,
                      R,
                      roots,
                      bodies,
                      collide,
                      damping,
                      h,
                      integrator,
                      stats):
    """
    Advance every segment by eq. 1, from root to tip, and place the vertices.

    Per segment: re-centre its chart, the moments of eq. 4, the update of eq. 6 (or the
    implicit variant), a clamp of the turn (counted), the position guard. A block of BLOCK
    segments (counted over all strands, root to tip) at a time: first their turns
    (_turn_packed_segments, vectorised; the few it marks by _turn_segment_exactly), then
    their vertices root to tip with the guard, a strand carried on into the next block.
    stats gets [MAX_RATE] the fastest a segment's end moved about its start (m/s),
    [RECHARTS], [GUARD_MOVES], [MIN_SIN_THETA] and [TURN_CLAMPS]. Returns the segments
    updated.
    """
    theta, phi, theta_prev, phi_prev = state.theta, state.phi, state.theta_prev, state.phi_prev
    chart, trig, packed, turned = state.chart, state.trig, state.packed, state.turned
    pos, pos_prev, length = strands.pos, strands.pos_prev, strands.length
    spheres, masks = bodies.spheres, bodies.masks
    n_s, n_seg = theta.shape
    max_sweep = 0.0
    recharts = 0
    guards = 0
    clamps = 0
    min_sin = 1.0
    s = 0
    i = 0
    px = py = pz = 0.0
    mask = np.int64(0)
    interleaved = (chart.reshape(-1), trig.reshape(-1), forces.f_dist.reshape(-1),
                   forces.f_end.reshape(-1), state.rest_dir.reshape(-1))
    contiguous = (theta.reshape(-1), phi.reshape(-1), theta_prev.reshape(-1),
                  phi_prev.reshape(-1), length.reshape(-1), state.k_hinge.reshape(-1),
                  state.inv_inertia.reshape(-1))
    for j0 in range(0, n_s * n_seg, BLOCK):
        n = min(BLOCK, n_s * n_seg - j0)
        j1 = j0 + n
        _pack_segments(interleaved, packed, R, j0, j1)
        cl, exact = _turn_packed_segments(packed, (contiguous[0][j0:j1], contiguous[1][j0:j1],
                                                   contiguous[2][j0:j1], contiguous[3][j0:j1],
                                                   contiguous[4][j0:j1], contiguous[5][j0:j1],
                                                   contiguous[6][j0:j1]),
                                          turned, damping, h, integrator)
        clamps += cl
        if exact > 0:
            s_j, i_j = s, i
            for j in range(n):
                if turned[TURN_EXACT * BLOCK + j] != 0.0:
                    rc, cl = _turn_segment_exactly(state, strands, forces, R, s_j, i_j, j,
                                                   damping, h, integrator)
                    recharts += rc
                    clamps += cl
                i_j += 1
                if i_j == n_seg:
                    i_j = 0
                    s_j += 1
        for j in range(n):
            if i == 0:                  # a strand starts: its root, with the head
                for v in range(n_seg + 1):
                    pos_prev[s, v, 0] = pos[s, v, 0]
                    pos_prev[s, v, 1] = pos[s, v, 1]
                    pos_prev[s, v, 2] = pos[s, v, 2]
                px, py, pz = roots[s, 0], roots[s, 1], roots[s, 2]
                pos[s, 0, 0], pos[s, 0, 1], pos[s, 0, 2] = px, py, pz
                mask = masks[s] if collide else np.int64(0)
            min_sin = min(min_sin, packed[PACK_SIN_TH * BLOCK + j])
            seg_len = length[s, i]
            new_th = turned[TURN_NEW_TH * BLOCK + j]
            new_ph = turned[TURN_NEW_PH * BLOCK + j]
            tr = (turned[TURN_SIN_TH * BLOCK + j], turned[TURN_COS_TH * BLOCK + j],
                  turned[TURN_SIN_PH * BLOCK + j], turned[TURN_COS_PH * BLOCK + j])
            ex = px + seg_len * turned[TURN_DX * BLOCK + j]
            ey = py + seg_len * turned[TURN_DY * BLOCK + j]
            ez = pz + seg_len * turned[TURN_DZ * BLOCK + j]
            moved = False
            if mask != 0:
                ex, ey, ez, moved = guard_segment((px, py, pz), (ex, ey, ez), seg_len, spheres,
                                                  mask, GUARD_LIFT)
            if moved:
                # contact: the segment is turned out of the sphere and stopped there (the
                # implicit update's previous angles: _stopped_keep)
                inv = 1.0 / seg_len
                C = _chart_of(chart, s, i)
                new_th, new_ph = _angles(C, (ex - px) * inv, (ey - py) * inv, (ez - pz) * inv)
                tr = _trig_of(new_th, new_ph)
                keep = 1.0
                if integrator == IMPLICIT:
                    rest_th, rest_ph = _angles(C, packed[PACK_RX * BLOCK + j],
                                               packed[PACK_RY * BLOCK + j],
                                               packed[PACK_RZ * BLOCK + j])
                    keep = _stopped_keep(state.k_hinge[s, i] * state.inv_inertia[s, i] * h * h,
                                         0.5 * damping * h)
                    theta_prev[s, i] = rest_th + keep * (new_th - rest_th)
                    phi_prev[s, i] = new_ph - (1.0 - keep) * wrap_angle(new_ph - rest_ph)
                else:
                    theta_prev[s, i] = new_th
                    phi_prev[s, i] = new_ph
                guards += 1
            else:
                theta_prev[s, i] = turned[TURN_TH * BLOCK + j]
                phi_prev[s, i] = new_ph - turned[TURN_D_PH * BLOCK + j]
            trig[s, i, SIN_TH], trig[s, i, COS_TH], trig[s, i, SIN_PH], trig[s, i, COS_PH] = tr
            wrapped = wrap_angle(new_ph)
            phi_prev[s, i] += wrapped - new_ph
            theta[s, i] = new_th
            phi[s, i] = wrapped
            sn = tr[SIN_TH]
            # (a stopped segment's previous angles are set for the next step, not a turn)
            turn = 0.0 if moved else \
                max(abs(new_th - theta_prev[s, i]), abs(wrapped - phi_prev[s, i]) * sn)
            sweep = turn * seg_len      # the end's path this step: its rate is sweep / h
            if sweep > max_sweep:
                max_sweep = sweep
            pos[s, i + 1, 0], pos[s, i + 1, 1], pos[s, i + 1, 2] = ex, ey, ez
            px, py, pz = ex, ey, ez
            i += 1
            if i == n_seg:
                i = 0
                s += 1
    # (one division: x / h is monotone in x, and so is its rounding)
    stats[MAX_RATE] = max_sweep / h
    stats[RECHARTS] += recharts
    stats[GUARD_MOVES] += guards
    stats[MIN_SIN_THETA] = min(stats[MIN_SIN_THETA], min_sin)
    stats[TURN_CLAMPS] += clamps
    return n_s * n_seg


@njit_without_refcounts
def thesis_substep(state,
                   strands,
                   forces,
                   bodies,
                   head,
                   attach,
                   wind,
                   springs,
                   settings,
                   h_prev,
                   h,
                   integrator,
                   damping,
                   stats):
    """
    Take one whole step of the thesis model in one call.

    Roots and spheres placed with the head, the broad phase, velocities, the forces of
    eqs. 5 and 7-11, the springs of 5.2, and eqs. 1-6 with the guard: the kernels the
    driver calls one by one for the other model, without the Python between them.

    springs is (StripSprings, SpringConstants). Return (broad-phase checks, contacts,
    wall springs, segments updated).
    """
    checks = place_with_head(head, attach, bodies, settings.collisions, settings.broad_phase)
    finite_difference_velocities(strands.pos, strands.pos_prev, h_prev, strands.vel)
    external_forces(strands, attach.root_acc, settings.gravity, wind, settings.wind_on,
                    settings.t, settings.drag_factor, settings.air_damping, True, forces)
    walls = 0
    if settings.inter_strip and springs[0].pairs.shape[0] > 0:
        walls = strip_springs(strands, bodies.spheres[:settings.n_scalp], springs[0],
                              springs[1], forces)
    contacts = 0
    if settings.collisions:
        # (the record of contacts is for a model that takes them implicitly: not this one;
        # the hinge springs as AnjyoSolver.contact_hinge gives them)
        contacts = reaction_constraint_forces(strands,
                                              bodies,
                                              settings.collision_stiffness,
                                              settings.collision_damping,
                                              False,
                                              forces,
                                              (state.chart, state.theta, state.phi, state.trig,
                                               state.rest_dir, state.k_hinge, head.R,
                                               state.theta_prev, state.phi_prev,
                                               state.inv_inertia,
                                               hold_weights(integrator, damping, h)))
    segments = integrate_strands(state, strands, forces, head.R, attach.roots, bodies,
                                 settings.collisions, damping, h, integrator, stats)
    return checks, contacts, walls, segments


@njit_without_refcounts
def finite_difference_velocities(pos, pos_prev, h_prev, vel):
    """Vertex velocities (pos - pos_prev) / h_prev: what this model knows of its speed."""
    inv_h = 1.0 / h_prev
    for s in range(pos.shape[0]):
        for j in range(pos.shape[1]):
            for a in range(3):
                vel[s, j, a] = (pos[s, j, a] - pos_prev[s, j, a]) * inv_h


def compensated_rest(modeled_dir, mass, length, k_hinge, params):
    """
    Return rest directions (head frame) whose equilibrium under gravity is the model.

    A styled hairstyle holds its shape: with gravity_compensation each hinge's rest
    direction (eq. 3) is turned against the gravity moment (eq. 4) it carries with the
    head upright, by -tau / k, so the modeled strands are the resting state. Turns are
    capped at 0.5 rad (hair too soft to hold such a style simply sags).
    """
    d = modeled_dir
    if not params.gravity_compensation:
        return d.copy()
    force = mass[..., None] * np.array([0.0, 0.0, -params.gravity])
    tau = 0.5 * length[..., None] * np.cross(d, force)       # about the start
    k = k_hinge[..., None]
    # no hinge (k = 0) can hold no style: then the hair simply hangs
    rot = np.where(k > 0, -tau / np.where(k > 0, k, 1.0), 0.0)
    angle = np.linalg.norm(rot, axis=-1, keepdims=True)
    capped = np.minimum(angle, 0.5)
    axis = rot / np.maximum(angle, 1e-300)
    c, s = np.cos(capped), np.sin(capped)
    out = d * c + np.cross(axis, d) * s + axis * (axis * d).sum(-1, keepdims=True) * (1 - c)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def contact_substeps(params, h):
    """Return how many equal substeps a step of h takes (CONTACT_SUBSTEP; else 1)."""
    if params.collisions and params.inter_strip and h > CONTACT_SUBSTEP:
        return ceil(h / CONTACT_SUBSTEP - 1e-9)
    return 1


class AnjyoSolver:
    """
    Thin class over the kernels above: per-segment angles, charts and hinge constants.

    Driven by HairSimulator, which owns the strands, the head and the shared forces.
    """

    name = 'anjyo'
    root_inertia = True             # segments swing about roots taken as fixed: -m a_root
    still_air_drag = False          # the thesis' drag acts with the wind only (eq. 5)
    holds_modeled_walls = False     # type-2 springs act within d2, as in thesis 5.2
    retries_diverged_steps = False  # MAX_TURN bounds a step's turn; nothing saved per step
    fused = True                    # a whole substep is one kernel call (thesis_substep)
    whole_step = False              # (a step's substeps are calls of their own)
    springs_before_contacts = True  # eq. 7 bears what the springs of 5.2 press with too
    uses_contacts = False        # the contact record (implicit contacts) is not read
    drops_inward_input = True    # eq. 7: the surface bears the inward input force
    contact_force_at_q = False   # eq. 10 moved to the end: a segment turns about its start
    blending = False             # (a material change takes effect at once: relax_material)
    forces_at_mid_step = False   # eqs. 4-6 take the forces where the step starts
    contact_damping_rate = 0.0   # eq. 8's c is collision_damping alone (explicit)

    def __init__(self, sim):
        n_s, n_seg = sim.length.shape
        self._substep_call = CompiledCall(thesis_substep)
        self.theta = np.zeros((n_s, n_seg))
        self.phi = np.zeros((n_s, n_seg))
        self.theta_prev = np.zeros((n_s, n_seg))
        self.phi_prev = np.zeros((n_s, n_seg))
        self.trig = np.zeros((n_s, n_seg, 4))
        self.chart = np.zeros((n_s, n_seg, 3, 3))
        self.packed = np.zeros(PACK_FIELDS * BLOCK)      # integrate_strands' scratch
        self.turned = np.zeros(TURN_FIELDS * BLOCK)
        self._counts = np.ones(n_s, dtype=np.int64)    # substeps_for's answer
        self.update_material(sim)

    def update_material(self, sim):
        """Recompute inertia, hinge stiffness (eq. 3) and rest directions from sim.params."""
        p = sim.params
        self._params = p                                            # (substeps_for)
        self.inv_inertia = 3.0 / (sim.mass * sim.length ** 2)         # rod about its end
        self.k_hinge = p.bending_stiffness / sim.length              # cantilever, eq. 3
        self.rest_dir = np.ascontiguousarray(compensated_rest(
            sim.modeled_dir, sim.mass, sim.length, self.k_hinge, p))

    def state(self):
        """Return the kernels' view of the arrays, shared and not copied."""
        return AnjyoState(theta=self.theta, phi=self.phi, theta_prev=self.theta_prev,
                          phi_prev=self.phi_prev, trig=self.trig, chart=self.chart,
                          rest_dir=self.rest_dir, inv_inertia=self.inv_inertia,
                          k_hinge=self.k_hinge, packed=self.packed, turned=self.turned)

    def contact_hinge(self, head, h, h_prev, params):
        """
        Return the hinge springs (eq. 3) as reaction_constraint_forces takes them.

        For a step of h after one of h_prev: the previous angles as match_previous_step
        will move them (copies; the kernels one by one, where step() moves them after the
        forces), as thesis_substep has them.
        """
        theta_prev, phi_prev = self.theta_prev, self.phi_prev
        if h != h_prev:
            theta_prev, phi_prev = self._previous_angles_for(h / h_prev)
        return (self.chart, self.theta, self.phi, self.trig, self.rest_dir, self.k_hinge,
                head.R, theta_prev, phi_prev, self.inv_inertia,
                hold_weights(_integrator_code(params), params.damping, h))

    def place(self, sim, world_dir):
        """Put every segment along world_dir (n_strands, n_segments, 3), at rest."""
        init_charts(np.ascontiguousarray(world_dir), self.chart, self.theta, self.phi,
                    self.trig)
        self.hold()

    def place_at_rest(self, sim):
        """Put every segment at its modeled direction under the current head, at rest."""
        self.place(sim, sim.modeled_dir @ sim.head_pose[0].T)

    def kinetic_energy(self, sim):
        """Return the kinetic energy (J) of the segments' centres over the last step."""
        v = (sim.pos - sim.pos_prev) / sim.last_dt
        vm = 0.5 * (v[:, 1:] + v[:, :-1])
        return float(0.5 * (sim.mass[..., None] * vm ** 2).sum())

    def relax_material(self, h):
        """Do nothing: the thesis model takes a material change at once."""

    def hold(self):
        """Forget the motion: the previous angles become the current ones (at rest)."""
        self.theta_prev[:] = self.theta
        self.phi_prev[:] = self.phi

    def rotate(self, dR):
        """Turn every segment rigidly by dR (a teleport of the head)."""
        rotate_charts(self.chart, dR)

    def velocities(self, sim, h_prev):
        """Fill sim.vel from the last step's displacement."""
        finite_difference_velocities(sim.pos, sim.pos_prev, h_prev, sim.vel)

    def match_previous_step(self, h, h_prev):
        """
        Move the previous angles so that eq. 6 carries the last step's speed over h.

        Eq. 6 is a Verlet update: x+ = 2x - x- + ... carries the last step's turn x - x-
        into the next step, whatever that step's length. A step of 1e-9 s after ones of
        1/60 s turned the tips as far as a 1/60 s step (1.7 cm on thesis_long in still
        air), and steps drawn from h/2 to 3h/2 made a pendulum swing 4 % fast. Here x-
        is put where the speed (x - x-) / h_prev had the angle one step of h ago, x - (h /
        h_prev)(x - x-) (time-corrected Verlet); equal steps leave it as it is.
        """
        if h == h_prev:
            return
        self.theta_prev[:], self.phi_prev[:] = self._previous_angles_for(h / h_prev)

    def _previous_angles_for(self, r):
        """Return (theta_prev, phi_prev) moved for a step r times the last (new arrays)."""
        turn = np.remainder(self.phi - self.phi_prev + pi, 2.0 * pi) - pi
        return self.theta - r * (self.theta - self.theta_prev), self.phi - r * turn

    def substep(self, sim, h, head, bodies, settings):
        """Take a whole (sub)step (forces and eqs. 1-6) in one kernel call; see thesis_substep."""
        p = sim.params
        self.match_previous_step(h, sim.last_dt)
        return self._substep_call(
            sim.layout_version,
            self.state(),
            sim.strands,
            sim.forces,
            bodies,
            head,
            sim.attachment,
            sim.wind.field,
            (sim._strip_springs, sim._spring_constants),
            settings,
            sim.last_dt,
            h,
            _integrator_code(p),
            p.damping,
            sim.stats,
        )

    def substeps_for(self, h):
        """
        Return each strand's substep count for a step of h: the same for every strand.

        With collisions and inter-strip springs, ceil(h / CONTACT_SUBSTEP) (a step up to
        it is taken whole); else 1: stability_problem and MAX_TURN bound the rest.
        """
        self._counts[:] = contact_substeps(self._params, h)
        return self._counts

    def step(self, sim, strand_h, head, strand_t):
        """
        Advance eqs. 1-6 with the forces in sim.forces; return segments updated.

        strand_h is each strand's step, strand_t when it ends; every strand takes the same
        substeps (substeps_for), so they are one h and one t.
        """
        p = sim.params
        self.match_previous_step(float(strand_h[0]), sim.last_dt)
        return integrate_strands(
            self.state(),
            sim.strands,
            sim.forces,
            head.R,
            sim.roots,
            sim.bodies,
            p.collisions,
            p.damping,
            float(strand_h[0]),
            _integrator_code(p),
            sim.stats,
        )

    @staticmethod
    def air_damping_rate(params):
        """Return the drag rate (1/s) against still air: air_damping (damping is eq. 1's)."""
        return params.air_damping

    @staticmethod
    def stability_problem(params, length, dt, margin):
        """
        Return why params would be unstable at dt for these segment lengths, or None.

        Judged at the substep the step is taken in (contact_substeps): a step over
        CONTACT_SUBSTEP with collisions and inter-strip springs is split, so eq. 6 and the
        explicit forces act over the substep.
        """
        n = contact_substeps(params, dt)
        reason = _substep_stability_problem(params, length, dt / n, margin)
        if reason and n > 1:
            reason += ' (a step of %.4g s is taken in %d substeps of %.4g s)' % (dt, n, dt / n)
        return reason


def _substep_stability_problem(params, length, dt, margin):
    """Return why params would be unstable at a (sub)step of dt, or None (see above)."""
    mass = params.linear_density * length
    inv_i = 3.0 / (mass * length ** 2)                              # rod about its end
    k_h = params.bending_stiffness / length
    springs = 0.0
    if params.inter_strip:
        springs += params.neighbor_stiffness + params.wall_stiffness + \
            params.scalp_stiffness
    if params.collisions:
        springs += params.collision_stiffness
    # per-metre springs on a segment of mass lambda l, acting at its end: k l * l^2 / I;
    # air damping acts on the centre, explicitly
    explicit = (0.5 * mass * params.gravity * length + springs * length ** 3) * inv_i
    if params.integrator == 'explicit':
        explicit = explicit + k_h * inv_i
        if params.damping * dt > 2.0 * margin:
            return ('damping %g/s with the explicit integrator needs dt below %.2g s'
                    % (params.damping, 2.0 * margin / params.damping))
    reason = explicit_stability_problem(explicit, params.air_damping, dt, margin,
                                        'the %s integrator' % params.integrator)
    if reason is None and params.integrator == 'explicit':
        # eq. 6 with its damping, x+ = 2x - x- - c h (x - x-) - w^2 h^2 x, is stable
        # while w^2 h^2 + 2 c h < 4 (Jury's test of z^2 - (2 - c h - w^2 h^2) z + 1 -
        # c h), at h / margin; each term under its own bound is not enough: at damping
        # 200/s and 1/120 s the stress bench's hair never came to rest
        w2 = float(np.max(explicit))
        c = params.damping
        if w2 > 0.0 and c > 0.0 and w2 * (dt / margin) ** 2 + 2.0 * c * dt / margin >= 4.0:
            reason = ('unstable with the explicit integrator at dt = %.4g s: damping %g/s '
                      'with its stiffest term at omega = %.0f rad/s needs dt below %.3g s'
                      % (dt, c, sqrt(w2), margin * (sqrt(c * c + 4.0 * w2) - c) / w2))
    return reason
