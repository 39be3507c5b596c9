"""
The exact strand model: a chain of rigid rods on spherical joints, O(segments) per strand.

Each segment is a rigid rod of mass m = lambda l spread along it (inertia m l^2 / 12 about
its centre across the rod; about its axis the rod's own 0.5 m r^2 with r the bundle's
radius), joined to its parent (the head, for the first) by a ball joint at its start. A
bending spring k = EI / l acts on the *relative* rotation between neighbouring segments,
the discrete curvature of the Hencky bar-chain: the torque on the child is -k R e, with
R_child = R_parent R_rest Exp(e) and e across the rod (a bend, see Twist below);
`root_stiffness_scale` multiplies the first joint's k (the follicle). `damping` (1/s) is
split between the two losses a strand has (`JOINT_DAMPING_SHARE`, `AIR_DAMPING_SHARE`):
dampers on the joints' relative angular velocities, d = share x damping x the inertia about
the joint of everything beyond it at the modeled pose (`inertia_beyond`), and a drag -share
x damping x m v on every segment's centre relative to still air (added to `air_damping`).
Twist: the joints are 2-DOF, no spin about a rod relative to its parent (`_without_twist` in
the articulated-body pass, the relative spin removed from the angular velocities, which
moves no vertex), and each joint is a pure bend: after every step a rod's frame is turned
about its own axis so that it is its rest frame under the parent turned by the minimal
rotation onto the rod (`twist_free_frame`), and the spring acts on that bend
(`bend_vector`, `_bend_deviation`), a function of the rods' directions alone. Without this
a sequence of bends twisted the frames (a joint swung round a cone comes back turned about
its axis) and the spring held the twist as a deviation for ever: strands came to rest off
their shape and rang on for seconds after violent motion. Nothing external twists a rod of
zero width, and a thin rod's twist inertia is tiny: with 3-DOF joints (a twist spring, as
MuJoCo's ball joints have), a joint holding a preload deflection e couples swing into twist
through its spring's tangent (skew part k [e]x / 2), and that light, stiff twist was flung
at thousands of rad/s: violent head motion diverged on every long style, and a preloaded
swing lost 43 % of its energy per 5 s. With 2-DOF joints the first runs 3 s without a
divergence and the second keeps its energy within 1 % (tested).

Dynamics are exact and coupled: every joint carries the inertia and weight of everything
beyond it. Featherstone's articulated-body algorithm, written for this chain in the world
frame with each body's reference point at its joint (3x3 blocks: the spatial transforms
between joints are pure translations along the rods):

- backward (tip to root): each body's inertia about its joint [[J, m[r]], [-m[r], m]],
  velocity-product bias and external wrench (the shared per-segment forces), plus the
  child's articulated inertia and bias seen through its joint, give the body's articulated
  inertia I^A and bias p^A; the ball joint's 3x3 D = A + c I gets the implicit spring and
  damper folded in, c = GAMMA h^2 k + h d (DART does this in its GenericJoint);
- forward (root to tip): joint accelerations q'' = D^-1 (u - U^T a_parent) from the head's
  own motion (the base motion: its angular acceleration and the root's acceleration),
  so a head turn's lag comes out of the dynamics, not from an added force; the root
  joint's spring, damper and twist lock work against the head where the strand is in the
  step, between the step's two poses (turned back from the end pose at the poses' own
  rate, HeadKinematics.turn), not against the end pose: that was a step's turn ahead,
  and a clamped follicle snapped onto it and back until the step diverged;
- the drift on SO(3): R <- Exp(h omega) R, in two parts around the kick (below).

The strands are stepped eight at a time, one in each lane of the vector registers
(LANES, step_chains): the same arithmetic, bit for bit, at half the cost.

The spring is taken at its deviation predicted GAMMA h ahead, -k (e + GAMMA h omega_rel+),
less a damping of the modes the step cannot resolve, -k GAMMA UNRESOLVED_DAMPING (b / (1 +
b))^4 h omega_rel, b = h^2 k / I: modes the step resolves (b << 1) keep their energy
(tested), while modes it cannot resolve (b >> 1) lose most of it every step instead of
ringing on. For a linear spring taking its force at the start (symplectic Euler) the step's
determinant is then 1 / (1 + (GAMMA + GAMMA UNRESOLVED_DAMPING (b / (1 + b))^4) b): stable
for any stiffness, also when the step's length changes from one step to the next, as the
substep count does with the swing (tested). The drift before the kick supplies theta h
omega_rel of the prediction, the spring's torque the rest. Taken as -k (e + GAMMA h
(omega_rel+ - omega_rel)) instead (as it was until 2026-11), a stiff joint carried a
velocity of order e / h into the next step, which a change of the step's length amplified:
alternating 1 and 2 substeps at 1/60 s diverged in 0.3 s, and in the hanging scene the
counts' own switching kept 20 of 50 strands moving 4-7 mm a second for ever. A stiff root
joint driven by a turning head grew at GAMMA = 0.3 (measured at 1/60 s); 0.5 holds.

The step is Stormer-Verlet in position form: part of the drift, the articulated-body pass
at the mid-step configuration, a kick, the rest of the drift (second order; the energy of
an undamped swinging strand stays within 0.3 % over 10 s at the default dt, tested). A
joint too stiff for the step takes its force at the start instead (the share theta of the
drift before the kick fades from 1/2 to 0 as b grows). The velocity-product terms use the
angular velocities predicted at mid-step from the last accelerations. Gravity and the
inter-strip springs stay explicit: `stability_problem` says when a setting needs a smaller
step. Contacts (eqs. 7-10, shared with the thesis model) act as forces whose stiffness and
damping are also folded into the articulated inertia, as an added mass at each contact
point (every contact of a segment: one left explicit has h c / m of about 4 at 1/60 s and
flung tips away); the position guard then turns a rod out of a sphere, and an inelastic impulse
through the articulated inertias (twist locked) stops that end's motion into the sphere
(`_stop_inward_motion`: positions alone, the joint springs the guard bent sped the end
inwards every step and violent head motion diverged). A step that
would turn a segment by more than MAX_STEP_ROTATION is split by the simulator, which
recomputes the forces for every substep. The simulator evaluates those forces at the
mid-step configuration, x + (h / 2) v, where Stormer-Verlet takes them (`forces_at_mid_step`):
taken at the start, a position-dependent force (a contact, an inter-strip spring) lags half
a step, which pumps energy into a strand at omega h / 2 per radian; at 1/60 s that beat the
joint dampers and strands resting on the head or on their neighbours shook 1-3 mm for ever.

Shape springs (optional, PhysicsParams.shape_stiffness; 0 by default, the exact chain): a
couple -kg e on every rod, kg = shape_stiffness l, e the rotation taking its modeled
direction under the head to its direction. The joint springs act between neighbours, so a
lock the wind blew over the crown rests there; these pull it back to the style, as the
thesis' absolute hinges and TressFX's global shape constraints do. The couple depends on
the rod's own absolute turn alone, so it is implicit like the joints' springs, taken at
its deviation predicted GAMMA h ahead: GAMMA h^2 kg is an added inertia across the rod (a
pure couple, so in its rotational block alone), the rest a damping of its turn relative to
the head, with the same numerical damping of modes the step cannot resolve. A hanging
chain's modes then match the Lagrangian with kg on each rod's absolute angle, undamped it
keeps its energy (kg e^2 / 2 included), and kg hundreds of times what a step resolves is stable
(tested).

Rest shape (sag-free): one recursive Newton-Euler pass at the modeled pose (head upright,
at rest, full distal loads; Hsu et al. 2023, Derouet-Jourdan et al. 2013) gives each
joint the torque that holds everything beyond it; the joint's spring gets an offset e0
that supplies exactly that, torque -k R (e - e0), and the modeled style is the equilibrium.
An equilibrium need not be stable: a strand that stands up against gravity falls off it
at the first touch unless its springs beat gravity's negative stiffness there, so each
strand's joints are stiffened until the pose's Hessian (springs plus `gravity_stiffness`)
is positive definite with STABILITY_MARGIN (`stiffness_to_hold`).
"""

from collections import namedtuple
from math import acos, atan2, cos, pi, sin, sqrt

from numba import njit, uint64
import numpy as np

from hair_sim.kernels import inlined_without_refcounts, njit_without_refcounts
from hair_sim.physics.forces import (CONTACT_C, CONTACT_FIELDS, CONTACT_K, CONTACT_LEVER,
                                     CONTACT_NX, CONTACT_NY, CONTACT_NZ, CONTACT_SLOTS,
                                     CONTACT_LOAD, CONTACT_LOAD_MID, CONTACT_SPHERE,
                                     clear_contact_record, explicit_stability_problem,
                                     external_forces,
                                     GUARD_LIFT, GUARD_MOVES, guard_segment, MAX_RATE,
                                     place_with_head, reaction_constraint_forces,
                                     Strands, strip_springs)
from hair_sim.physics.compiled_call import CompiledCall
from hair_sim.physics.multirate import multirate_substep

# weight of the implicit spring increment: >= 1/4 is stable for a still base; a stiff root
# joint driven by a turning head grew at 0.3 (measured, 1/60 s) and holds at 0.5
GAMMA = 0.5
UNRESOLVED_DAMPING = 0.5     # share of a step's spring increment that damps unresolved modes
# rad a segment may turn in one substep: at 0.1 the tips of 20-segment strands falling
# over the head whipped up and diverged (hanging scene, 1/60 to 1/240 s); with 2-DOF
# joints and retried steps, 0.1 still let bob_fringe diverge under violent motion (3 s:
# once at 1/60 s, 3 times at 1/240 s) while halving the demo's cost (0.4-0.6 s per s);
# and away from the head it keeps a free swing accurate: a damped ten-rod chain released
# from horizontal ends 0.90 mm from its Lagrangian (scipy) at 1/60 s with 0.05, 1.01 mm
# with 0.06 and 1.55 mm with 0.1 for the rods far from every sphere (design_notes.md)
MAX_STEP_ROTATION = 0.05
# at most this many substeps per step: at 64, violent head motion at one step per 60 Hz
# frame (tips near 300 rad/s) ran out of substeps and bob_fringe diverged twice in 3 s
MAX_SUBSTEPS = 256
# a strand that ends a step needing more than this many times the substeps it took has
# outrun its count (`outran`): the simulator takes the step again at the count the swing
# at its end needs (strands joined by springs: all of them, at the most any needs)
OUTRAN_FACTOR = 16
# A strand nothing can give energy to (the head still, no wind, no spring to another
# strand, no vertex but its root within FREE_CLEARANCE of a sphere) that ends a step with
# more energy than it began it with, by more than this times its weight times its length,
# has outrun its count too (`gained_energy`): a stiff follicle let go far from its rest
# rose up to 3.9 times above its release in 40 of 144 random releases (energies of 90 m g L
# and more), in steps clipped at MAX_SUBSTEPS and in steps whose whip grew 2.5 times
# within them, both under OUTRAN_FACTOR. A step's own error stays well under it: the
# hanging scene's 10-segment strands falling at 1/60 s gain up to 7e-4 m g L in a step
# (design_notes.md)
ENERGY_SLACK = 1e-2
FREE_CLEARANCE = 0.01        # m
# rad of spring deflection a joint may need to hold its style (sag-free offsets); beyond it
# the joint is stiffened: measured, offsets past ~1 rad (up to 7.9 on the long styles,
# past pi the log coordinates wrap) made the hair boil under calm head motion
MAX_PRELOAD = 1.0
# a style's pose must be stable, not only an equilibrium: each strand's joint stiffness is
# at least this many times what gravity's negative stiffness at that pose needs
STABILITY_MARGIN = 1.5
STABILITY_CHUNK_BYTES = 16 << 20     # the stability check's Hessians, at most, at a time
# How `damping` is spent. Joint dampers alone cannot make a long strand settle quickly:
# in the linear modes of a hanging 25-30 cm chain (M, C, K of its Lagrangian) the slowest
# decays at 1.2/s at best, whatever their scale (too little: it swings on; too much: an
# overdamped creep), and a strand crept back for 5 s after a shake. Drag against the air
# (mass proportional) damps what the joints cannot: with a fifth of the rate on the joints
# and a third as drag (12/s: 2.4/s and 4/s) the slowest mode of hanging 20-30 cm chains,
# and of a standing one stiffened to stand (STABILITY_MARGIN), decays at 2.3-2.6/s.
JOINT_DAMPING_SHARE = 0.2
AIR_DAMPING_SHARE = 1.0 / 3.0
# s: a change of the material while the hair moves (set_params: stiffness, root stiffness,
# mass, gravity) brings each joint's stiffness geometrically from the old to the new over
# this long (smoothstep), while the preload torques k e0 that hold the style take their
# new values at once (so the modeled pose stays the equilibrium throughout, and a change
# of the load alone takes effect at once). Applied at once, a stiffened joint held away
# from its rest by the motion got the energy k e^2 / 2 of its new stiffness in one step:
# raising root_stiffness_scale to 1e4 or more mid-motion diverged the articulated model
# every time (thesis_short, 1/60 and 1/240 s), and the hair was reset. Over 0.25 s, a
# 100 times stiffer material set mid-motion flung the tips at 7.6 m/s, 2.6 times the
# faster material's own peak under the same motion; over 1 s, 4.6 m/s (1.6 times).
# (Keeping each joint's torque by its offset alone, at the new stiffness at once, was not
# enough: a joint 1e4 times stiffer held at a 114 deg bend diverged at once.)
MATERIAL_BLEND_S = 1.0
# The shape springs blend geometrically as well, so that a stiff one set while the hair is
# far from its style pulls it back at the pace of a soft one first; from (or to) 0 they
# start (or end) at this share of the other end's stiffness. Blended linearly over the
# same second, shape_stiffness 10 set in the middle of violent motion flung thesis_short's
# tips at 7.2 m/s, 2.5 times the exact chain's own peak under the same motion.
SHAPE_BLEND_FLOOR = 1e-4
# Contacts are implicit here, so they can stop a segment's motion into a sphere instead of
# letting it bounce: their damping (eq. 8's c, per metre) gets this rate times the mass per
# metre on top of collision_damping (200/s: +0.5 N s/m per m for the default material).
# Without it, after 2 s of violent motion at 1/60 s, bob_fringe and side_swept_long were
# still moving 8 s later (fringe strands on the forehead shaking 1-2 mm, turned out by the
# guard every step) and thesis_long slept after 4.7 s; with it 6.9, 2.9 and 2.7 s.
CONTACT_DAMPING_RATE = 200.0
# The contact impulses of one strand are coupled through its chain: one pass, root to tip,
# let the impulse at a tip undo part of the one at the segment before it (seen after the
# stress bench's random run, on a strand with two guarded ends: the first moved inwards at
# 0.02 m/s again at every step). Sweeps repeat (projected Gauss-Seidel on the impulses,
# each >= 0) until no velocity changes by more than IMPULSE_TOLERANCE (m/s), at most
# IMPULSE_SWEEPS times; the same for the contacts before the drift (_speculative_contacts).
IMPULSE_SWEEPS = 32
IMPULSE_TOLERANCE = 1e-7
# Eq. 7 for the chain: the surface bears what presses on it, and no more. The contact
# impulses above do that exactly, through the articulated inertias, for every force that
# presses (gravity, wind, the inter-strip springs and the joint springs alike), so no share
# of the input force is dropped before them (forces.reaction_constraint_forces' drop_input).
# The thesis model's share is ramped over the 1 mm contact skin by distance and counts only
# the input forces; the chain's joint springs are not among them. A strand pair of
# thesis_long, hanging after violent motion with its tips 0.7-1.2 mm off a body sphere,
# had part of gravity's pull dropped while its sag-free springs went on lifting, and swung
# 0.6-1.1 mm at 2.9 Hz for ever (1/60 and 1/240 s, at two of seven stops of the motion);
# without the share it sleeps 6.3-6.9 s after the stop.
DROPS_INWARD_INPUT = False
# The guard's chord allowance (forces.guard_segment): a segment whose inner point dips into
# a sphere deeper than SEGMENT_TOLERANCE plus the sag of a chord resting on it is turned
# out. The thesis model fades that sag over the 1 mm contact skin with the start's height;
# a segment longer than sqrt(8 r 1 mm) (2.4 cm on a 7.5 cm scalp sphere: a sag over 1 mm)
# then loses allowance faster than its start rises, so a chain at rest on the head, its
# vertices a fraction of a mm up, had chords the guard turned out every step: each lifted
# end took allowance from the next segment and gravity pulled them back, a ratchet that
# slid strands over the head. After the stress bench's gale (thesis_long, 1/60 s, with
# contact_friction 0.3) it turned 27 segments out every step for seconds, tips kept
# 18-21 mm/s that the guard undid and slid 1.9 mm/s, 5.9e-7 J of motion stayed, and the
# hair slept only 5.65 s after the wind stopped. Here the sag fades mm for mm with the
# height of the segment's lower end, so a resting chord is left alone (a flying segment
# still gets SEGMENT_TOLERANCE): the same run sleeps after 3.4 s (frictionless, 8.2 s:
# strands slide back round the head). Since the contact impulses bear what presses
# (DROPS_INWARD_INPUT) resting vertices sit about 1 um up instead of hovering in the skin,
# which weakens that ratchet but does not end it: with the old allowance, 6 strands let
# fall over a ball (test_contact_friction) had the guard turn 11-12 segments out a step
# for their second second, and with contact_friction 0.5 never slept within 10 s.
SAG_BY_HEIGHT = True
# Eq. 10's chord contact acts on the chain at its point Q (forces.reaction_constraint_forces'
# force_at_q): the chain passes a force on to the parents, which the thesis model's segments
# do not
CONTACT_FORCE_AT_Q = True

# air: the rate (1/s) of the drag -air m v on every segment's centre that the shared forces
# apply explicitly at the start of the step; the chain adds its implicit half (see below)
# shape_k, shape_dir: each segment's shape spring (N m/rad; 0: none) and its modeled
# direction in the head frame (PhysicsParams.shape_stiffness)
ChainState = namedtuple('ChainState', ['R', 'omega', 'alpha', 'rest_rel', 'k', 'd',
                                       'inertia_axial',
                                       'offset', 'air', 'friction', 'sag_by_height',
                                       'shape_k', 'shape_dir'])
# step_chains' scratch (chain_scratch), reused for every step: the lanes' fields (W, see
# LANES), their strands and the guard's moves in them, and one strand's articulated pass
# and contacts at a time (the strand-by-strand contact solves)
ChainScratch = namedtuple('ChainScratch', ['W', 'lanes', 'slots', 'l_guarded', 'l_gnrm',
                                           'Dinv', 'U_A', 'U_B', 'alpha',
                                           'guarded', 'g_nrm', 'u_imp', 'dw', 'rc_imp',
                                           'lam_imp', 'c_seg', 'c_lever', 'c_nrm', 'c_bound',
                                           'c_load', 'c_lam', 'c_fric', 'c_dw',
                                           'c_dvn', 'c_dwb', 'c_K'])


# ------------------------------------------------------------------ 3x3 helpers
@njit_without_refcounts
def _cross3(a, b):
    """Return the cross product a x b of two 3-tuples."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit_without_refcounts
def _scaled_outer3(c, a, b):
    """Return the 9-tuple of c a b^T, each entry (c a_i) b_j."""
    return (c * a[0] * b[0], c * a[0] * b[1], c * a[0] * b[2],
            c * a[1] * b[0], c * a[1] * b[1], c * a[1] * b[2],
            c * a[2] * b[0], c * a[2] * b[1], c * a[2] * b[2])


@njit_without_refcounts
def _inverse_sym3(A):
    """Return the inverse of a symmetric positive definite 3x3 matrix (9-tuples)."""
    a, b, c = A[0], A[1], A[2]
    d, e, f = A[4], A[5], A[8]
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    det = a * c00 + b * c01 + c * c02
    inv = 1.0 / det
    o01, o02, o12 = c01 * inv, c02 * inv, (b * c - a * e) * inv
    return (c00 * inv, o01, o02,
            o01, (a * f - c * c) * inv, o12,
            o02, o12, (a * d - b * b) * inv)


@njit_without_refcounts
def _without_twist(S, dx, dy, dz):
    """
    Return the joint's inverse S = D^-1 made that of a 2-DOF joint: no twist (9-tuples).

    The limit of (D + kappa d d^T)^-1 as kappa grows (Sherman-Morrison): S - (S d)(S d)^T /
    (d^T S d), d the rod's axis. The relative acceleration S y is then always across the
    rod. See the module text for why the joints do not twist.
    """
    g0 = S[0] * dx + S[1] * dy + S[2] * dz
    g1 = S[3] * dx + S[4] * dy + S[5] * dz
    g2 = S[6] * dx + S[7] * dy + S[8] * dz
    q = g0 * dx + g1 * dy + g2 * dz
    return (S[0] - g0 * g0 / q, S[1] - g0 * g1 / q, S[2] - g0 * g2 / q,
            S[3] - g1 * g0 / q, S[4] - g1 * g1 / q, S[5] - g1 * g2 / q,
            S[6] - g2 * g0 / q, S[7] - g2 * g1 / q, S[8] - g2 * g2 / q)


@njit_without_refcounts
def _load3(A):
    """Return the 3x3 array A as a row-major 9-tuple."""
    return (A[0, 0], A[0, 1], A[0, 2], A[1, 0], A[1, 1], A[1, 2], A[2, 0], A[2, 1], A[2, 2])


@njit_without_refcounts
def _store3(m, out):
    """Write the 9-tuple m into the 3x3 array out."""
    out[0, 0], out[0, 1], out[0, 2] = m[0], m[1], m[2]
    out[1, 0], out[1, 1], out[1, 2] = m[3], m[4], m[5]
    out[2, 0], out[2, 1], out[2, 2] = m[6], m[7], m[8]


@njit_without_refcounts
def _mul3(a, b):
    """Return the product a b of two 9-tuples (sums left to right, as the loops had them)."""
    return (a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
            a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
            a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
            a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
            a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
            a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8])


@njit_without_refcounts
def _transpose3(a):
    """Return the transpose of a 9-tuple."""
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


@njit_without_refcounts
def _add3(a, b):
    """Return a + b of two 9-tuples."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5],
            a[6] + b[6], a[7] + b[7], a[8] + b[8])


@njit_without_refcounts
def _sub3(a, b):
    """Return a - b of two 9-tuples."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4], a[5] - b[5],
            a[6] - b[6], a[7] - b[7], a[8] - b[8])


@njit_without_refcounts
def _apply3(a, x, y, z):
    """Return a (x, y, z) for a 9-tuple a."""
    return (a[0] * x + a[1] * y + a[2] * z,
            a[3] * x + a[4] * y + a[5] * z,
            a[6] * x + a[7] * y + a[8] * z)


@njit_without_refcounts
def _apply_both3(a, x, b, y):
    """Return a x + b y for 9-tuples a, b and 3-tuples x, y (one sum, left to right)."""
    return (a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + b[0] * y[0] + b[1] * y[1] + b[2] * y[2],
            a[3] * x[0] + a[4] * x[1] + a[5] * x[2] + b[3] * y[0] + b[4] * y[1] + b[5] * y[2],
            a[6] * x[0] + a[7] * x[1] + a[8] * x[2] + b[6] * y[0] + b[7] * y[1] + b[8] * y[2])


# below this squared angle, rotation_series gives Rodrigues' coefficients to 3e-18
SERIES_TH2 = 0.01


@inlined_without_refcounts
def rotation_series(th2):
    """
    Return (sin(th) / th, (1 - cos(th)) / th^2) by their series, for th^2 < SERIES_TH2.

    Under 0.1 rad (twice a substep's turn, MAX_STEP_ROTATION) the next terms are under
    3e-18. Measured on the hanging scene at 200 x 20: the chain step 0.245 -> 0.219 us a
    segment, for its two calls of sin and cos per segment; and no cancellation in
    1 - cos(th). Arithmetic only: a lane loop calling it vectorises.
    """
    s = 1.0 - th2 * (1.0 / 6.0 - th2 * (1.0 / 120.0 - th2 * (
        1.0 / 5040.0 - th2 * (1.0 / 362880.0))))
    c1 = 0.5 - th2 * (1.0 / 24.0 - th2 * (1.0 / 720.0 - th2 * (
        1.0 / 40320.0 - th2 * (1.0 / 3628800.0))))
    return s, c1


@njit_without_refcounts
def rotation_coefficients(th2):
    """Return (sin(th) / th, (1 - cos(th)) / th^2): the series below SERIES_TH2, else libm."""
    if th2 < SERIES_TH2:
        return rotation_series(th2)
    th = sqrt(th2)
    return sin(th) / th, (1.0 - cos(th)) / th2


@inlined_without_refcounts
def rotation_from(wx, wy, wz, s, c1):
    """Return Rodrigues' rotation matrix of w from its coefficients s and c1 (a 9-tuple)."""
    return (1.0 - c1 * (wy * wy + wz * wz), c1 * wx * wy - s * wz, c1 * wx * wz + s * wy,
            c1 * wx * wy + s * wz, 1.0 - c1 * (wx * wx + wz * wz), c1 * wy * wz - s * wx,
            c1 * wx * wz - s * wy, c1 * wy * wz + s * wx, 1.0 - c1 * (wx * wx + wy * wy))


@njit_without_refcounts
def rotation_exp(wx, wy, wz):
    """Return the rotation matrix Exp([w]) of a rotation vector (Rodrigues), a 9-tuple."""
    s, c1 = rotation_coefficients(wx * wx + wy * wy + wz * wz)
    return rotation_from(wx, wy, wz, s, c1)


@inlined_without_refcounts
def _orthonormalized(m):
    """
    Return the 9-tuple m with its columns made orthonormal, z (the rod) first.

    Gram-Schmidt: keeps R a rotation under roundoff.
    """
    zx, zy, zz = m[2], m[5], m[8]
    n = sqrt(zx * zx + zy * zy + zz * zz)
    zx, zy, zz = zx / n, zy / n, zz / n
    xx, xy, xz = m[0], m[3], m[6]
    dot = xx * zx + xy * zy + xz * zz
    xx, xy, xz = xx - dot * zx, xy - dot * zy, xz - dot * zz
    n = sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / n, xy / n, xz / n
    return (xx, zy * xz - zz * xy, zx,
            xy, zz * xx - zx * xz, zy,
            xz, zx * xy - zy * xx, zz)


@inlined_without_refcounts
def twist_free_rotation(Rp, rest_rel, R):
    """
    Return R turned about its own rod axis so that the joint from Rp is a pure bend.

    The joints have two degrees of freedom: the child's frame is its rest frame under the
    parent, A = Rp rest_rel, turned by the minimal rotation that takes A's z to the rod's
    axis d (about z x d): Rp^T R = rest_rel Exp(e) with e across the rod. The step's
    velocities have no relative spin, but a sequence of bends still twists a frame (the
    holonomy of rotations: a joint swung round a cone comes back turned about its axis),
    and the spring on the whole relative rotation then held that twist as a deviation for
    ever: after a gale and violent motion a standing strand rested 26 mm from where the
    same strand kicked from rest came to rest, and rang for 4 s (root joint: 0.66 rad).
    This moves no vertex (d is kept); the bending energy becomes a function of the rods'
    directions alone, as in the Hencky bar-chain. A rod bent back on its rest axis (d = -z)
    keeps its frame. Rotations are row-major 9-tuples.
    """
    A = _mul3(Rp, rest_rel)
    dx, dy, dz = R[2], R[5], R[8]
    vx = A[0] * dx + A[3] * dy + A[6] * dz        # d in A's frame
    vy = A[1] * dx + A[4] * dy + A[7] * dz
    vz = A[2] * dx + A[5] * dy + A[8] * dz
    c = 1.0 + vz
    if c < 1e-9:
        return R
    # minimal rotation z -> v: I + [k] + [k]^2 / (1 + v_z), k = z x v (columns x, y, v)
    return _mul3(A, (1.0 - vx * vx / c, -vx * vy / c, vx,
                     -vx * vy / c, 1.0 - vy * vy / c, vy,
                     -vx, -vy, vz))


@njit_without_refcounts
def twist_free_frame(Rp, rest_rel, R):
    """Turn the 3x3 array R about its own rod axis, in place (twist_free_rotation)."""
    _store3(twist_free_rotation(_load3(Rp), _load3(rest_rel), _load3(R)), R)


@njit(cache=True)
def twist_free_chains(R, rest_rel, Rh):
    """twist_free_frame for every joint, root to tip (R: n_strands, n_segments, 3, 3)."""
    for s in range(R.shape[0]):
        for i in range(R.shape[1]):
            twist_free_frame(Rh if i == 0 else R[s, i - 1], rest_rel[s, i], R[s, i])


@inlined_without_refcounts
def joint_rotation_of(Rp, rest_rel, Ri):
    """Return S = rest_rel^T Rp^T Ri: the joint's rotation from its rest (9-tuples)."""
    return _mul3(_transpose3(_mul3(Rp, rest_rel)), Ri)


@njit_without_refcounts
def joint_rotation(Rp, rest_rel, Ri, out):
    """Write S = rest_rel^T Rp^T Ri: the joint's rotation from its rest (child from parent)."""
    _store3(joint_rotation_of(_load3(Rp), _load3(rest_rel), _load3(Ri)), out)


@njit_without_refcounts
def _bend_angle(vx, vy, vz):
    """Return (theta, sin theta, f = theta / sin theta) of the bend from z to the unit v."""
    st = sqrt(vx * vx + vy * vy)
    t = atan2(st, vz)
    return t, st, _theta_over_sine(t, st)


@inlined_without_refcounts
def _theta_over_sine(t, st):
    """Return f = theta / sin(theta) of a bend (its series near 0)."""
    return 1.0 + t * t / 6.0 if t < 1e-3 else t / max(st, 1e-300)


@njit_without_refcounts
def bend_vector(S):
    """
    Return (e, theta, sin theta) of the bend S: e = theta (z x v) / |z x v|, v = S z.

    The rotation vector of the minimal rotation from the rest axis z to the rod's axis v
    (= log S when S is twist-free): the discrete curvature of the Hencky bar-chain.
    """
    vx, vy = S[0, 2], S[1, 2]
    t, st, f = _bend_angle(vx, vy, S[2, 2])
    return (-f * vy, f * vx, 0.0), t, st


# ------------------------------------------------------------------ the chain step
@inlined_without_refcounts
def _preload_weight(t, st, vz):
    """
    Return (sigma, d sigma / d theta) of the bend's preload at bend angle t (see bend_energy).

    1 up to a right angle, sin(theta) beyond: C1 at pi / 2, and 0 at pi.
    """
    if t <= 0.5 * pi:
        return 1.0, 0.0
    return st, vz


@njit_without_refcounts
def bend_energy(S, e0):
    """
    Return the bend spring's energy over k for the joint rotation S and preload e0.

    |e - e0|^2 / 2 with e the bend (bend_vector), that is (theta^2 - 2 theta n.e0 +
    |e0|^2) / 2 with n the bend's unit axis; the preload's term is weighted by
    sigma(theta) (_preload_weight: 1 up to a right angle, sin(theta) beyond). Unweighted,
    the energy jumps across a fold (theta = pi, where n turns round), and the torque near
    one grew like 1 / sin(theta): after 2 s of violent head motion in a 30 m/s gale at
    1/60 s, the articulated model diverged in 5 of 16 runs (thesis_short, bob_fringe,
    side_swept_long), each time a root joint folded past ~170 deg being flung at
    10^4 rad/s in one substep. A style's preload stays below MAX_PRELOAD (1 rad), where
    sigma is 1: its rest shapes and their stability are unchanged.
    """
    return _bend_energy_of_axis(S[0, 2], S[1, 2], S[2, 2], e0)


@njit_without_refcounts
def _bend_energy_of_axis(vx, vy, vz, e0):
    """bend_energy from the rod's axis v = S z in the joint's rest frame."""
    t, st, f = _bend_angle(vx, vy, vz)
    # sigma theta n.e0, with g = z x v = sin(theta) n: f g.e0 up to a right angle (sigma =
    # 1, f = theta / sin(theta)), theta g.e0 beyond (sigma = sin(theta))
    ge0 = -vy * e0[0] + vx * e0[1]
    pre = f * ge0 if t <= 0.5 * pi else t * ge0
    return 0.5 * (t * t - 2.0 * pre + e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2])


@njit_without_refcounts
def strand_energies(chain,
                    material,
                    R_head,
                    gravity,
                    which,
                    out):
    """
    Each strand's energy (J) into out (n_strands,): motion, weight and springs.

    chain is (R, omega, pos, vel), the state to measure; material is (mass, length,
    inertia_axial, rest_rel, k, offset, shape_dir, shape_k), as the solver holds them;
    R_head the head's rotation. Only the strands where `which` is set are measured (the
    others are left as they are). The terms are those of kinetic_energy and
    potential_energy, strand by strand, with gravity's m g z at each rod's centre.
    """
    R, omega, pos, vel = chain
    mass, length, inertia_axial, rest_rel, k, offset, shape_dir, shape_k = material
    head = _load3(R_head)
    for s in range(R.shape[0]):
        if not which[s]:
            continue
        total = 0.0
        # the parent's frame (the head's for the first rod), by columns
        px = (head[0], head[3], head[6])
        py = (head[1], head[4], head[7])
        pz = (head[2], head[5], head[8])
        for i in range(R.shape[1]):
            m = mass[s, i]
            vx = 0.5 * (vel[s, i, 0] + vel[s, i + 1, 0])
            vy = 0.5 * (vel[s, i, 1] + vel[s, i + 1, 1])
            vz = 0.5 * (vel[s, i, 2] + vel[s, i + 1, 2])
            dx, dy, dz = R[s, i, 0, 2], R[s, i, 1, 2], R[s, i, 2, 2]
            wx, wy, wz = omega[s, i, 0], omega[s, i, 1], omega[s, i, 2]
            wd = wx * dx + wy * dy + wz * dz
            w_perp2 = wx * wx + wy * wy + wz * wz - wd * wd
            ip = m * length[s, i] * length[s, i] / 12.0
            total += 0.5 * m * (vx * vx + vy * vy + vz * vz)
            total += 0.5 * (ip * w_perp2 + inertia_axial[s, i] * wd * wd)
            total += m * gravity * 0.5 * (pos[s, i, 2] + pos[s, i + 1, 2])
            # the bend: S z = rest_rel^T Rp^T d, the rod's axis d in the joint's rest frame
            # (joint_rotation_of's third column)
            ax = px[0] * dx + px[1] * dy + px[2] * dz
            ay = py[0] * dx + py[1] * dy + py[2] * dz
            az = pz[0] * dx + pz[1] * dy + pz[2] * dz
            rr = rest_rel[s, i]
            total += k[s, i] * _bend_energy_of_axis(
                rr[0, 0] * ax + rr[1, 0] * ay + rr[2, 0] * az,
                rr[0, 1] * ax + rr[1, 1] * ay + rr[2, 1] * az,
                rr[0, 2] * ax + rr[1, 2] * ay + rr[2, 2] * az,
                offset[s, i])
            if shape_k[s, i] > 0.0:
                # the shape spring: its rod against its modeled direction, turned with the head
                mx = head[0] * shape_dir[s, i, 0] + head[1] * shape_dir[s, i, 1] + \
                    head[2] * shape_dir[s, i, 2]
                my = head[3] * shape_dir[s, i, 0] + head[4] * shape_dir[s, i, 1] + \
                    head[5] * shape_dir[s, i, 2]
                mz = head[6] * shape_dir[s, i, 0] + head[7] * shape_dir[s, i, 1] + \
                    head[8] * shape_dir[s, i, 2]
                c = min(1.0, max(-1.0, mx * dx + my * dy + mz * dz))
                a = acos(c)
                total += 0.5 * shape_k[s, i] * a * a
            px = (R[s, i, 0, 0], R[s, i, 1, 0], R[s, i, 2, 0])
            py = (R[s, i, 0, 1], R[s, i, 1, 1], R[s, i, 2, 1])
            pz = (dx, dy, dz)
        out[s] = total


@njit_without_refcounts
def bend_deviation_of(S, e0):
    """Return bend_deviation_at the bend's angle (_bend_angle of S's rod axis)."""
    return bend_deviation_at(S, e0, _bend_angle(S[2], S[5], S[8])[0])


@inlined_without_refcounts
def bend_deviation_at(S, e0, t):
    """
    Return the bend spring's generalised deviation q (child frame): torque -k R q.

    S is the joint's rotation from rest (joint_rotation_of, a 9-tuple), v = S z the rod's
    axis in the rest frame, theta its angle from z and n = z x v / sin(theta) the bend's
    axis. The spring's energy k E (bend_energy) is a function of v alone (the joints have
    no twist).
    A turn delta of the rod changes theta by delta.n and the bend plane's azimuth psi by
    delta.m / sin(theta), m = (z - v cos(theta)) / sin(theta), so the torque is -k
    (dE/dtheta n + dE/dpsi / sin(theta) m), written without the cancellations of a
    Cartesian gradient (near a fold those lost every digit). (The gradient over all
    rotations, J_r(e)^-T (e - e0) with e = log S, counts the frame's twist as a
    deviation: a sequence of bends twists a frame, and that twist was held for ever.
    Within a step the frames drift off twist-free, so e is taken from v alone.) A rod
    folded back onto its rest axis (v = -z) gets no torque. t is the bend's angle theta,
    atan2(sin(theta), S[8]) (a lane loop takes it from libm in a scalar pass of its own:
    the rest is arithmetic and selects, and vectorises).
    """
    vx, vy, vz = S[2], S[5], S[8]
    st = sqrt(vx * vx + vy * vy)
    f = _theta_over_sine(t, st)
    if t < 1e-3:
        # near rest: the Cartesian gradient of |e - e0|^2 / 2, with f to O(theta^4)
        wx, wy = -f * vy - e0[0], f * vx - e0[1]      # w = e - e0 (e_z = 0)
        fp = -(1.0 / 3.0 + 2.0 * t * t / 15.0)        # df / dv_z
        gw = -vy * wx + vx * wy
        ax, ay, az = f * wy, -f * wx, fp * gw         # grad_v E
        qx, qy, qz = vy * az - vz * ay, vz * ax - vx * az, vx * ay - vy * ax   # v x grad
    elif st > 1e-12:
        nx, ny = -vy / st, vx / st                    # n (n_z = 0)
        ne = nx * e0[0] + ny * e0[1]                  # n.e0
        te = -ny * e0[0] + nx * e0[1]                 # (z x n).e0 = dn/dpsi . e0
        sigma, dsigma = _preload_weight(t, st, vz)
        d_theta = t - (sigma + t * dsigma) * ne       # dE / dtheta
        # dE/dpsi / sin(theta) = -theta sigma te / sin(theta); sigma / sin(theta) = 1 past
        # a right angle
        d_psi = -t * (sigma / st if t <= 0.5 * pi else 1.0) * te
        mx, my, mz = -vx * vz / st, -vy * vz / st, st  # m
        qx = d_theta * nx + d_psi * mx
        qy = d_theta * ny + d_psi * my
        qz = d_psi * mz
    else:
        return (0.0, 0.0, 0.0)
    return (S[0] * qx + S[3] * qy + S[6] * qz,
            S[1] * qx + S[4] * qy + S[7] * qz,
            S[2] * qx + S[5] * qy + S[8] * qz)


@njit_without_refcounts
def _bend_deviation(S, e0, q):
    """Write bend_deviation_of the 3x3 array S into q."""
    q[0], q[1], q[2] = bend_deviation_of(_load3(S), e0)


@njit_without_refcounts
def _unit_impulse_response(s,
                           i,
                           contact,
                           chain,
                           articulated,
                           scratch):
    """
    Return the contact point's velocity change along nrm per unit impulse along nrm.

    The projection of _unit_impulse_velocity (same arguments; it writes dw).
    """
    nrm = contact[0]
    cx, cy, cz = _unit_impulse_velocity(s, i, contact, chain, articulated, scratch)
    return cx * nrm[0] + cy * nrm[1] + cz * nrm[2]


@njit_without_refcounts
def _unit_impulse_velocity(s,
                           i,
                           contact,
                           chain,
                           articulated,
                           scratch):
    """
    Return the chain's response to a unit impulse along nrm at rc (from joint i), segment i.

    Featherstone's test-force propagation through the articulated inertias of this step
    (the joints' implicit springs and dampers included, the head held): the bias of the
    impulse, p = -(rc x n, n), goes from joint i to the root, then accelerations come back
    out from the root to the tip. contact is (nrm, rc), chain (R, length), articulated
    (Dinv, U_A, U_B) of this step, scratch (u, dw). Writes the angular velocity changes dw
    (n_seg, 3) and returns the contact point's velocity change (x, y, z) per unit impulse.
    """
    nrm, rc = contact
    R, length = chain
    Dinv, U_A, U_B = articulated
    u, dw = scratch
    n_seg = dw.shape[0]
    pa0 = -(rc[1] * nrm[2] - rc[2] * nrm[1])
    pa1 = -(rc[2] * nrm[0] - rc[0] * nrm[2])
    pa2 = -(rc[0] * nrm[1] - rc[1] * nrm[0])
    pl0, pl1, pl2 = -nrm[0], -nrm[1], -nrm[2]
    for j in range(n_seg):
        u[j, 0] = u[j, 1] = u[j, 2] = 0.0
    for j in range(i, -1, -1):
        u[j, 0], u[j, 1], u[j, 2] = -pa0, -pa1, -pa2
        if j == 0:
            break
        y0 = Dinv[j, 0, 0] * u[j, 0] + Dinv[j, 0, 1] * u[j, 1] + Dinv[j, 0, 2] * u[j, 2]
        y1 = Dinv[j, 1, 0] * u[j, 0] + Dinv[j, 1, 1] * u[j, 1] + Dinv[j, 1, 2] * u[j, 2]
        y2 = Dinv[j, 2, 0] * u[j, 0] + Dinv[j, 2, 1] * u[j, 1] + Dinv[j, 2, 2] * u[j, 2]
        # p^a = p^A + U D^-1 u, U = [J; B^T]
        pa0 += U_A[j, 0, 0] * y0 + U_A[j, 0, 1] * y1 + U_A[j, 0, 2] * y2
        pa1 += U_A[j, 1, 0] * y0 + U_A[j, 1, 1] * y1 + U_A[j, 1, 2] * y2
        pa2 += U_A[j, 2, 0] * y0 + U_A[j, 2, 1] * y1 + U_A[j, 2, 2] * y2
        pl0 += U_B[j, 0, 0] * y0 + U_B[j, 1, 0] * y1 + U_B[j, 2, 0] * y2
        pl1 += U_B[j, 0, 1] * y0 + U_B[j, 1, 1] * y1 + U_B[j, 2, 1] * y2
        pl2 += U_B[j, 0, 2] * y0 + U_B[j, 1, 2] * y1 + U_B[j, 2, 2] * y2
        # to the parent's joint, back along the parent rod a: p_ang += a x p_lin
        lp = length[s, j - 1]
        ax, ay, az = lp * R[s, j - 1, 0, 2], lp * R[s, j - 1, 1, 2], lp * R[s, j - 1, 2, 2]
        pa0 += ay * pl2 - az * pl1
        pa1 += az * pl0 - ax * pl2
        pa2 += ax * pl1 - ay * pl0
    al0 = al1 = al2 = 0.0                  # the head does not respond
    lx = ly = lz = 0.0
    cx = cy = cz = 0.0
    for j in range(n_seg):
        if j > 0:
            lp = length[s, j - 1]
            bx, by, bz = lp * R[s, j - 1, 0, 2], lp * R[s, j - 1, 1, 2], lp * R[s, j - 1, 2, 2]
            lx += al1 * bz - al2 * by
            ly += al2 * bx - al0 * bz
            lz += al0 * by - al1 * bx
        t0 = u[j, 0] - (U_A[j, 0, 0] * al0 + U_A[j, 0, 1] * al1 + U_A[j, 0, 2] * al2
                        + U_B[j, 0, 0] * lx + U_B[j, 0, 1] * ly + U_B[j, 0, 2] * lz)
        t1 = u[j, 1] - (U_A[j, 1, 0] * al0 + U_A[j, 1, 1] * al1 + U_A[j, 1, 2] * al2
                        + U_B[j, 1, 0] * lx + U_B[j, 1, 1] * ly + U_B[j, 1, 2] * lz)
        t2 = u[j, 2] - (U_A[j, 2, 0] * al0 + U_A[j, 2, 1] * al1 + U_A[j, 2, 2] * al2
                        + U_B[j, 2, 0] * lx + U_B[j, 2, 1] * ly + U_B[j, 2, 2] * lz)
        al0 += Dinv[j, 0, 0] * t0 + Dinv[j, 0, 1] * t1 + Dinv[j, 0, 2] * t2
        al1 += Dinv[j, 1, 0] * t0 + Dinv[j, 1, 1] * t1 + Dinv[j, 1, 2] * t2
        al2 += Dinv[j, 2, 0] * t0 + Dinv[j, 2, 1] * t1 + Dinv[j, 2, 2] * t2
        dw[j, 0], dw[j, 1], dw[j, 2] = al0, al1, al2
        if j == i:
            cx = lx + al1 * rc[2] - al2 * rc[1]
            cy = ly + al2 * rc[0] - al0 * rc[2]
            cz = lz + al0 * rc[1] - al1 * rc[0]
    return cx, cy, cz


@njit_without_refcounts
def _point_responses(s, i, rc, chain, articulated, u, dwb, K):
    """
    Write a point's responses to unit impulses along x, y and z (segment i, at rc).

    dwb[a] (n_seg, 3) the joints' angular velocity changes for an impulse along axis a,
    K[a] the point's velocity change (_unit_impulse_velocity).
    """
    for a in range(3):
        K[a, 0] = K[a, 1] = K[a, 2] = 0.0
        K[a, a] = 1.0
        vx, vy, vz = _unit_impulse_velocity(s, i, (K[a], rc), chain, articulated,
                                            (u, dwb[a]))
        K[a, 0], K[a, 1], K[a, 2] = vx, vy, vz


@njit_without_refcounts
def _response_along(K, tx, ty, tz):
    """Return t . (K t): the velocity change along the unit t per unit impulse along it."""
    return (tx * (tx * K[0, 0] + ty * K[1, 0] + tz * K[2, 0])
            + ty * (tx * K[0, 1] + ty * K[1, 1] + tz * K[2, 1])
            + tz * (tx * K[0, 2] + ty * K[1, 2] + tz * K[2, 2]))


@inlined_without_refcounts
def _without_relative_spin(w, parent_w, d):
    """
    Return angular velocity w less its spin about the rod axis d relative to parent_w.

    The joints are 2-DOF: a rod turns about its parent (or the head) only across its axis.
    """
    tw = (w[0] - parent_w[0]) * d[0] + (w[1] - parent_w[1]) * d[1] + \
        (w[2] - parent_w[2]) * d[2]
    return w[0] - tw * d[0], w[1] - tw * d[1], w[2] - tw * d[2]


@njit_without_refcounts
def _rigid_articulated_inertias(s, R, length, mass, inertia_axial, articulated):
    """
    Write strand s's articulated inertias of its rods alone, as they are now (D^-1, U).

    The backward pass of _joint without the step's implicit terms (the joints' springs
    and dampers, the drag's and the contacts' added masses) and at the chain's present
    configuration R: what an impulse meets at an instant. articulated is (Dinv, U_A, U_B)
    (n_seg, 3, 3), overwritten.
    """
    Dinv, U_A, U_B = articulated
    n_seg = length.shape[1]
    CA = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    CB = CA
    CM = CA
    for i in range(n_seg - 1, -1, -1):
        seg = length[s, i]
        m = mass[s, i]
        ia = inertia_axial[s, i]
        dx, dy, dz = R[s, i, 0, 2], R[s, i, 1, 2], R[s, i, 2, 2]
        ip = m * seg * seg / 3.0
        j01, j02, j12 = (ia - ip) * dx * dy, (ia - ip) * dx * dz, (ia - ip) * dy * dz
        Jm = _add3((ip + (ia - ip) * dx * dx, j01, j02,
                    j01, ip + (ia - ip) * dy * dy, j12,
                    j02, j12, ip + (ia - ip) * dz * dz), CA)
        r0, r1, r2 = 0.5 * seg * dx, 0.5 * seg * dy, 0.5 * seg * dz
        Bm = _add3((0.0, -r2 * m, r1 * m, r2 * m, 0.0, -r0 * m, -r1 * m, r0 * m, 0.0), CB)
        Mm = _add3((m, 0.0, 0.0, 0.0, m, 0.0, 0.0, 0.0, m), CM)
        Sm = _without_twist(_inverse_sym3(Jm), dx, dy, dz)
        _store3(Sm, Dinv[i])
        _store3(Jm, U_A[i])
        _store3(Bm, U_B[i])
        if i == 0:
            break
        Aa = _sub3(Jm, _mul3(Jm, _mul3(Sm, Jm)))
        SB = _mul3(Sm, Bm)
        Ba = _sub3(Bm, _mul3(Jm, SB))
        Ma = _sub3(Mm, _mul3(_transpose3(Bm), SB))
        lp = length[s, i - 1]
        ax, ay, az = lp * R[s, i - 1, 0, 2], lp * R[s, i - 1, 1, 2], lp * R[s, i - 1, 2, 2]
        Ka = (0.0, -az, ay, az, 0.0, -ax, -ay, ax, 0.0)
        KM = _mul3(Ka, Ma)
        CA = _sub3(_add3(_sub3(Aa, _mul3(Ba, Ka)), _mul3(Ka, _transpose3(Ba))),
                   _mul3(KM, Ka))
        CB = _add3(Ba, KM)
        CM = Ma


@njit_without_refcounts
def _stop_inward_motion(s,
                        contacts,
                        chain,
                        base,
                        head,
                        articulated,
                        scratch,
                        vel):
    """
    Apply an inelastic contact impulse at every end the guard moved, through the chain.

    The guard moves positions only; left alone, the end's inward velocity would be kept,
    and the joint springs the guard bent would speed it up every step (measured: angular
    velocities grew without bound under violent head motion). Each guarded end gets the
    impulse along the guard's direction that stops its motion into the sphere relative to
    the head (the head's surface velocity v + w x (x - p)), through the articulated
    inertias of the rods alone where the chain now is (_rigid_articulated_inertias), so
    every segment of the chain responds as an impact says (Featherstone's test-force
    propagation): a plastic impact, which takes motion and never gives any. (Through the
    step's articulated inertias, with its joints' implicit springs and the contacts'
    added masses in them, the impulse was spread as over a step, not an instant, and
    could give a chain motion.) The ends of one chain are coupled: sweeps
    root to tip mend each end's accumulated impulse (never pulling) until none changes a
    velocity by more than IMPULSE_TOLERANCE (projected Gauss-Seidel); then the vertex
    velocities are placed again. contacts is (guarded, normal) per segment, chain (R,
    omega, length), base the roots' (positions, velocities), articulated the rods'
    (Dinv, U_A, U_B), scratch (u, dw, rc, the accumulated impulses).
    """
    guarded, g_nrm = contacts
    R, omega, length = chain
    roots, root_vel = base
    u, dw, rc, lam = scratch
    n_seg = guarded.shape[0]
    for i in range(n_seg):
        lam[i] = 0.0
    for sweep in range(IMPULSE_SWEEPS):
        largest = 0.0                       # the largest velocity change of this sweep
        for i in range(n_seg):
            if not guarded[i]:
                continue
            # the end's velocity now (h = 0: omega as it is), relative to the head's surface
            vx, vy, vz = _point_velocity(s, i, 1.0, chain, base, head, u, 0.0, rc)
            nrm = g_nrm[i]
            vn = vx * nrm[0] + vy * nrm[1] + vz * nrm[2]
            if vn >= 0.0 and lam[i] == 0.0:
                continue
            dvn = _unit_impulse_response(s,
                                         i,
                                         (nrm, rc),
                                         (R, length),
                                         articulated,
                                         (u, dw))
            if dvn <= 1e-300:
                continue
            # the impulse so far, mended towards vn = 0 and never pulling (>= 0)
            total = max(0.0, lam[i] - vn / dvn)
            d_lam = total - lam[i]
            lam[i] = total
            for j in range(n_seg):
                omega[s, j, 0] += d_lam * dw[j, 0]
                omega[s, j, 1] += d_lam * dw[j, 1]
                omega[s, j, 2] += d_lam * dw[j, 2]
            largest = max(largest, abs(d_lam * dvn))
        if largest <= IMPULSE_TOLERANCE:
            break
    vx, vy, vz = root_vel[s, 0], root_vel[s, 1], root_vel[s, 2]
    for j in range(n_seg):
        seg = length[s, j]
        dx, dy, dz = R[s, j, 0, 2], R[s, j, 1, 2], R[s, j, 2, 2]
        parent_w = (head.turn[0], head.turn[1], head.turn[2]) if j == 0 else \
            (omega[s, j - 1, 0], omega[s, j - 1, 1], omega[s, j - 1, 2])
        omega[s, j, 0], omega[s, j, 1], omega[s, j, 2] = _without_relative_spin(
            (omega[s, j, 0], omega[s, j, 1], omega[s, j, 2]), parent_w, (dx, dy, dz))
        bx, by, bz = seg * dx, seg * dy, seg * dz
        vx += omega[s, j, 1] * bz - omega[s, j, 2] * by
        vy += omega[s, j, 2] * bx - omega[s, j, 0] * bz
        vz += omega[s, j, 0] * by - omega[s, j, 1] * bx
        vel[s, j + 1, 0], vel[s, j + 1, 1], vel[s, j + 1, 2] = vx, vy, vz


@njit_without_refcounts
def _point_velocity(s,
                    i,
                    lever,
                    chain,
                    base,
                    head,
                    alpha,
                    h,
                    rc):
    """
    Return a point's velocity after the kick, relative to the head's surface there.

    The point is at lever (0..1) along segment i of strand s, and the kick's angular
    velocities are omega + h alpha. Writes the point's offset from the joint of segment i
    into rc.
    """
    R, omega, length = chain
    roots, root_vel = base
    vx, vy, vz = root_vel[s, 0], root_vel[s, 1], root_vel[s, 2]
    px, py, pz = roots[s, 0], roots[s, 1], roots[s, 2]
    for j in range(i + 1):
        lj = length[s, j] * (lever if j == i else 1.0)
        bx, by, bz = lj * R[s, j, 0, 2], lj * R[s, j, 1, 2], lj * R[s, j, 2, 2]
        wx = omega[s, j, 0] + h * alpha[j, 0]
        wy = omega[s, j, 1] + h * alpha[j, 1]
        wz = omega[s, j, 2] + h * alpha[j, 2]
        vx += wy * bz - wz * by
        vy += wz * bx - wx * bz
        vz += wx * by - wy * bx
        px += bx
        py += by
        pz += bz
        if j == i:
            rc[0], rc[1], rc[2] = bx, by, bz
    rx, ry, rz = px - head.p[0], py - head.p[1], pz - head.p[2]
    return (vx - (head.v[0] + head.w[1] * rz - head.w[2] * ry),
            vy - (head.v[1] + head.w[2] * rx - head.w[0] * rz),
            vz - (head.v[2] + head.w[0] * ry - head.w[1] * rx))


@njit_without_refcounts
def _speculative_contacts(s,
                          contact,
                          chain,
                          base,
                          head,
                          spheres,
                          articulated,
                          scratch,
                          alpha,
                          h,
                          friction):
    """
    Limit each contact point's approach to its sphere, and its sliding, before the drift.

    The kick's angular velocities, omega + h alpha, may carry a contact point of strand s
    into its sphere; the drift would then put it inside, the guard turn it back out and
    an impulse stop it after the fact (a strand pressed into the head kept a velocity the
    guard undid every step: measured 0.04-0.05 m/s at the tips of strands that did not
    move, after the stress bench's random run). Here every point the contact record holds
    (its segment, lever and sphere; normal and gap taken again at this configuration)
    may approach by at most its gap (less GUARD_LIFT) in the step, v_n >= -gap / h, and
    never move inwards once inside. Its sliding relative to the head's surface is opposed
    by a tangential impulse of at most friction times its normal impulse: this step's
    normal impulse plus h times the load the surface already bears there (the penalty of
    eq. 8, from the contact record; no share of the input force is dropped for this model,
    DROPS_INWARD_INPUT, so the normal impulse carries what presses). The impulses, accumulated,
    the normal ones never pulling, are mended over the strand's contacts until none
    changes a velocity by more than IMPULSE_TOLERANCE (projected Gauss-Seidel through the
    articulated inertias of this step), and go into alpha. chain is (R, omega, length),
    base the roots' (positions, velocities), scratch (u, rc, and per point: segments,
    levers, normals, bounds, loads, normal and friction impulses, normal responses and
    their size along the normal, responses to impulses along x, y and z and the point's
    velocity changes for them). Returns the points held.
    """
    R, omega, length = chain
    roots, root_vel = base
    (u, rc, c_seg, c_lever, c_nrm, c_bound, c_load, c_lam, c_fric, c_dw, c_dvn, c_dwb,
     c_K) = scratch
    n_seg = length.shape[1]
    n_c = 0
    jx, jy, jz = roots[s, 0], roots[s, 1], roots[s, 2]      # the joint of segment i
    for i in range(n_seg):
        seg = length[s, i]
        dx, dy, dz = R[s, i, 0, 2], R[s, i, 1, 2], R[s, i, 2, 2]
        for q in range(CONTACT_SLOTS):
            slot = q * CONTACT_FIELDS
            if contact[s, i, slot + CONTACT_K] + contact[s, i, slot + CONTACT_C] <= 0.0:
                break
            lever = contact[s, i, slot + CONTACT_LEVER]
            k = int(contact[s, i, slot + CONTACT_SPHERE])
            ex = jx + lever * seg * dx - spheres[k, 0]
            ey = jy + lever * seg * dy - spheres[k, 1]
            ez = jz + lever * seg * dz - spheres[k, 2]
            dist = sqrt(ex * ex + ey * ey + ez * ez)
            if dist < 1e-12:
                continue
            nx, ny, nz = ex / dist, ey / dist, ez / dist
            # the point itself; and the segment's middle, where eq. 7's dropped
            # distributed force was borne (friction only; none when DROPS_INWARD_INPUT
            # is False)
            for mid in range(2):
                load = contact[s, i, slot + (CONTACT_LOAD_MID if mid else CONTACT_LOAD)]
                if mid and (load <= 0.0 or friction <= 0.0):
                    break
                c_seg[n_c] = i
                c_lever[n_c] = 0.5 if mid else lever
                c_nrm[n_c, 0], c_nrm[n_c, 1], c_nrm[n_c, 2] = nx, ny, nz
                # (-inf: no normal constraint at the middle)
                c_bound[n_c] = -np.inf if mid else \
                    -max(dist - spheres[k, 3] - GUARD_LIFT, 0.0) / h
                c_load[n_c] = load
                c_lam[n_c] = 0.0
                c_dvn[n_c] = -1.0
                c_K[n_c, 0, 0] = -1.0               # (its friction responses: not yet)
                c_fric[n_c, 0] = c_fric[n_c, 1] = c_fric[n_c, 2] = 0.0
                n_c += 1
        jx += seg * dx
        jy += seg * dy
        jz += seg * dz
    if n_c == 0:
        return 0
    for sweep in range(IMPULSE_SWEEPS):
        largest = 0.0
        for c in range(n_c):
            i = c_seg[c]
            lever = c_lever[c]
            nrm = c_nrm[c]
            vn = 0.0
            if c_bound[c] > -np.inf:            # (a middle: friction only)
                vx, vy, vz = _point_velocity(s, i, lever, chain, base, head, alpha, h, rc)
                vn = vx * nrm[0] + vy * nrm[1] + vz * nrm[2]
            if c_bound[c] > -np.inf and (vn < c_bound[c] or c_lam[c] > 0.0):
                if c_dvn[c] < 0.0:              # the response is the step's: kept
                    c_dvn[c] = _unit_impulse_response(s,
                                                      i,
                                                      (nrm, rc),
                                                      (R, length),
                                                      articulated,
                                                      (u, c_dw[c]))
                dvn = c_dvn[c]
                if dvn > 1e-300:
                    total = max(0.0, c_lam[c] + (c_bound[c] - vn) / dvn)
                    d_lam = total - c_lam[c]
                    c_lam[c] = total
                    for j in range(n_seg):
                        alpha[j, 0] += d_lam * c_dw[c, j, 0] / h
                        alpha[j, 1] += d_lam * c_dw[c, j, 1] / h
                        alpha[j, 2] += d_lam * c_dw[c, j, 2] / h
                    largest = max(largest, abs(d_lam * dvn))
            cap = friction * (c_lam[c] + h * c_load[c])
            if cap <= 0.0 and c_fric[c, 0] == 0.0 and c_fric[c, 1] == 0.0 and \
                    c_fric[c, 2] == 0.0:
                continue
            # Coulomb: an impulse against the sliding, the one that stops it along its
            # direction, added to this point's so far and kept within |impulse| <= cap.
            # The point's responses to impulses along x, y and z, worked out once a step,
            # give the response along any direction (the chain's response is linear):
            # two propagations a sweep saved
            vx, vy, vz = _point_velocity(s, i, lever, chain, base, head, alpha, h, rc)
            if c_K[c, 0, 0] < 0.0:
                _point_responses(s, i, rc, (R, length), articulated, u, c_dwb[c], c_K[c])
            K = c_K[c]
            vn = vx * nrm[0] + vy * nrm[1] + vz * nrm[2]
            ux, uy, uz = vx - vn * nrm[0], vy - vn * nrm[1], vz - vn * nrm[2]
            slide = sqrt(ux * ux + uy * uy + uz * uz)
            wx, wy, wz = c_fric[c, 0], c_fric[c, 1], c_fric[c, 2]
            if slide > 1e-300:
                tx, ty, tz = ux / slide, uy / slide, uz / slide
                d_t = _response_along(K, tx, ty, tz)
                if d_t > 1e-300:
                    wx -= slide / d_t * tx
                    wy -= slide / d_t * ty
                    wz -= slide / d_t * tz
            size = sqrt(wx * wx + wy * wy + wz * wz)
            if size > cap:
                wx, wy, wz = wx * cap / size, wy * cap / size, wz * cap / size
            ex_, ey_, ez_ = wx - c_fric[c, 0], wy - c_fric[c, 1], wz - c_fric[c, 2]
            step = sqrt(ex_ * ex_ + ey_ * ey_ + ez_ * ez_)
            if step <= 1e-300:
                continue
            c_fric[c, 0], c_fric[c, 1], c_fric[c, 2] = wx, wy, wz
            d_e = _response_along(K, ex_ / step, ey_ / step, ez_ / step)
            dwb = c_dwb[c]
            for j in range(n_seg):
                for a in range(3):
                    alpha[j, a] += (ex_ * dwb[0, j, a] + ey_ * dwb[1, j, a]
                                    + ez_ * dwb[2, j, a]) / h
            largest = max(largest, abs(step * d_e))
        if largest <= IMPULSE_TOLERANCE:
            break
    return n_c


@njit_without_refcounts
def strand_swings(R, omega, out):
    """
    Write each strand's fastest swing (rad/s) into out.

    A swing is a rod's angular velocity across its axis; the strand's is its fastest rod's.
    Spin about a rod moves nothing. A strand with a NaN anywhere gets NaN (a diverged state).
    """
    for s in range(R.shape[0]):
        top = 0.0
        for i in range(R.shape[1]):
            dx, dy, dz = R[s, i, 0, 2], R[s, i, 1, 2], R[s, i, 2, 2]
            wx, wy, wz = omega[s, i, 0], omega[s, i, 1], omega[s, i, 2]
            wd = wx * dx + wy * dy + wz * dz
            sx, sy, sz = wx - wd * dx, wy - wd * dy, wz - wd * dz
            sw = sx * sx + sy * sy + sz * sz
            if sw != sw:
                top = np.nan
                break
            if sw > top:
                top = sw
        out[s] = sqrt(top)


# ------------------------------------------------------------------ the chain step, in lanes
# step_chains steps LANES strands at once, each in a lane of every field of a flat scratch
# W, in loops over the lanes that LLVM turns into vector instructions (eight strands in one
# AVX-512 register, two AVX2 ones): a strand's step is a chain of dependent 3x3 products
# down and up its segments, so one strand at a time waits on its chain, not on arithmetic
# (measured: one 3x3 product fewer per segment changed nothing), while eight independent
# chains fill the vector units. The arithmetic of every lane is the scalar step's, operation
# for operation (no fast-math), so the result is the same bit for bit; where that needs
# libm (the bend angle's atan2, Rodrigues' sine and cosine past SERIES_TH2), a short scalar
# pass over the lanes takes it between two vector loops. Measured on the hanging scene at
# 200 x 20, one step per 60 Hz frame: 0.36 -> 0.18 us a segment-substep (see
# BENCHMARKS.md). What varies from strand to strand in its control flow (the speculative
# contacts, the position guard, the impulse that stops inward motion) runs strand by strand
# on the lane's copy, as it did.
LANES = 8
# W holds LANES lanes of each field of n_seg + 1 records: record 0 is the head (the root
# joint's base: its frames, turn and angular acceleration, the root's position and
# velocity), record i + 1 segment i. Every lane loop reaches its segment's and its
# parent's fields at constant offsets from one base, so that LLVM proves them apart and
# vectorises (fields of a second array, or a field's offset that depends on the segment
# apart from the base, need run-time overlap checks, and it gave up); indices are unsigned
# (no wraparound branch).
G_R0 = 0         # the frame at the step's start (9)
G_RM = 9         # ... at mid-step (9); the head: at mid-step
G_OM = 18        # the angular velocity at the step's start (3); the head: its turn
G_WM = 21        # ... predicted at mid-step (3)
G_TH = 24        # the share of the drift before the kick
G_W = 25         # a drift's rotation vector (3)
G_S = 28         # ... its Rodrigues coefficients sin(th) / th and (1 - cos(th)) / th^2
G_C1 = 29
G_DI = 30        # the joint's D^-1 (9)
G_UA = 39        # U: J (9)
G_UB = 48        # B (9)
G_U = 57         # u (3)
G_AL = 60        # the angular acceleration (3); the head: its own
G_LA = 63        # the joint's linear acceleration (3)
G_REST = 66      # rest_rel (9)
G_LEN = 75       # length
G_M = 76         # mass
G_K = 77         # joint stiffness
G_IAX = 78       # axial inertia
G_SK = 79        # shape spring
G_ALP = 80       # the last step's angular acceleration (3)
G_H = 83         # the lane's step
G_NC = 84        # contacts of this segment (the record's leading slots)
G_CT = 85        # their stiffness, damping, lever and normal (CONTACT_SLOTS x 6)
G_CQ = G_CT + 6 * CONTACT_SLOTS   # the slot being added, and whether the lane has it (7)
G_FD = G_CQ + 7                   # the distributed force (3)
G_FE = G_FD + 3                   # the end force (3)
G_OFF = G_FE + 3                  # the spring's offset (3)
G_D = G_OFF + 3                   # the joint damper
G_SD = G_D + 1                    # the shape spring's direction in the head frame (3)
G_JM = G_SD + 3                   # the body's J, B, M, p_ang, p_lin before the joint
G_BM = G_JM + 9
G_MM = G_BM + 9
G_PA = G_MM + 9
G_PL = G_PA + 3
G_CA = G_PL + 3                   # its children's articulated inertia and bias seen at its
G_CB = G_CA + 9                   # joint (A, B, M, p_ang, p_lin)
G_CM = G_CB + 9
G_CPA = G_CM + 9
G_CPL = G_CPA + 3
G_SJ = G_CPL + 3                  # the joint's rotation from rest (9)
G_ST = G_SJ + 9                   # ... its bend's sine
G_T = G_ST + 1                    # ... and angle
G_RN = G_T + 1                    # the new frame before the twist is taken out (9)
G_WN = G_RN + 9                   # the new angular velocity (3)
G_E = G_WN + 3                    # the end (3); the head: the root
G_V = G_E + 3                     # its velocity (3); the head: the root's
G_RF = G_V + 3                    # the new frame (9); the head: at the step's end
G_WF = G_RF + 9                   # the new angular velocity (3); the head: its turn
G_RATE = G_WF + 3                 # the end's speed about the start
SEG_FIELDS = G_RATE + 1


@njit_without_refcounts
def _ix(f, ln):
    """Return the index in W of lane ln of field f (unsigned: no wraparound branch)."""
    return uint64(f * LANES + ln)


@njit_without_refcounts
def _get(W, f, ln):
    return W[_ix(f, ln)]


@njit_without_refcounts
def _get3(W, f, ln):
    return W[_ix(f, ln)], W[_ix(f + 1, ln)], W[_ix(f + 2, ln)]


@njit_without_refcounts
def _get9(W, f, ln):
    return (W[_ix(f, ln)], W[_ix(f + 1, ln)], W[_ix(f + 2, ln)],
            W[_ix(f + 3, ln)], W[_ix(f + 4, ln)], W[_ix(f + 5, ln)],
            W[_ix(f + 6, ln)], W[_ix(f + 7, ln)], W[_ix(f + 8, ln)])


@njit_without_refcounts
def _put(W, f, ln, x):
    W[_ix(f, ln)] = x


@njit_without_refcounts
def _put3(W, f, ln, x):
    W[_ix(f, ln)] = x[0]
    W[_ix(f + 1, ln)] = x[1]
    W[_ix(f + 2, ln)] = x[2]


@njit_without_refcounts
def _put9(W, f, ln, m):
    for a in range(9):
        W[_ix(f + a, ln)] = m[a]


@njit_without_refcounts
def _rec(i):
    """Return the first field of segment i's record (-1: the head's)."""
    return (i + 1) * SEG_FIELDS


@njit_without_refcounts
def _put_turn(W, g, ln, w):
    """Keep a drift's rotation vector w and its Rodrigues coefficients by their series."""
    _put3(W, g + G_W, ln, w)
    s, c1 = rotation_series(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    _put(W, g + G_S, ln, s)
    _put(W, g + G_C1, ln, c1)


@njit_without_refcounts
def _turn(W, g, ln):
    """Return the rotation matrix of the drift kept (its coefficients taken)."""
    wx, wy, wz = _get3(W, g + G_W, ln)
    return rotation_from(wx, wy, wz, _get(W, g + G_S, ln), _get(W, g + G_C1, ln))


@njit_without_refcounts
def _take_rotation_coefficients(W, i):
    """Rodrigues' coefficients of the lanes whose drift of segment i turns past the series."""
    g = _rec(i)
    for ln in range(LANES):
        wx, wy, wz = _get3(W, g + G_W, ln)
        th2 = wx * wx + wy * wy + wz * wz
        if th2 >= SERIES_TH2:
            s, c1 = rotation_coefficients(th2)
            _put(W, g + G_S, ln, s)
            _put(W, g + G_C1, ln, c1)


@njit_without_refcounts
def _drift_turn(W, i):
    """Work out the share theta of segment i's drift before the kick, its turn, its rate."""
    g = _rec(i)
    for ln in range(LANES):
        h = _get(W, g + G_H, ln)
        seg = _get(W, g + G_LEN, ln)
        bi = h * h * (_get(W, g + G_K, ln) + _get(W, g + G_SK, ln)) / (
            _get(W, g + G_M, ln) * seg ** 2 / 3.0 + _get(W, g + G_IAX, ln))
        theta = 0.5 / (1.0 + bi ** 4)
        ox, oy, oz = _get3(W, g + G_OM, ln)
        px, py, pz = _get3(W, g + G_ALP, ln)
        _put3(W, g + G_WM, ln, (ox + theta * h * px, oy + theta * h * py,
                                oz + theta * h * pz))
        _put_turn(W, g, ln, (theta * h * ox, theta * h * oy, theta * h * oz))
        _put(W, g + G_TH, ln, theta)


@njit_without_refcounts
def _drift_to_mid(W, i):
    """Turn segment i's frame by its drift to mid-step (the coefficients taken)."""
    g = _rec(i)
    for ln in range(LANES):
        _put9(W, g + G_RM, ln, _orthonormalized(_mul3(_turn(W, g, ln), _get9(W, g + G_R0, ln))))


@njit_without_refcounts
def _body_inertia(W, i, air):
    """
    Body i of the backward pass: its inertia about its joint, its bias and wrench.

    Writes J, B, M, p_ang, p_lin of the body alone (G_JM .. G_PL); see step_chains.
    """
    g = _rec(i)
    for ln in range(LANES):
        h = _get(W, g + G_H, ln)
        seg = _get(W, g + G_LEN, ln)
        m = _get(W, g + G_M, ln)
        Ri = _get9(W, g + G_RM, ln)
        dx, dy, dz = Ri[2], Ri[5], Ri[8]
        r = (0.5 * seg * dx, 0.5 * seg * dy, 0.5 * seg * dz)
        # the drag's implicit half as an added mass cw at the centre
        cw = 0.5 * h * air * m
        ip = m * seg * seg / 3.0 + 0.25 * cw * seg * seg
        ia = _get(W, g + G_IAX, ln)
        j01, j02, j12 = (ia - ip) * dx * dy, (ia - ip) * dx * dz, (ia - ip) * dy * dz
        Jm = (ip + (ia - ip) * dx * dx, j01, j02,
              j01, ip + (ia - ip) * dy * dy, j12,
              j02, j12, ip + (ia - ip) * dz * dz)
        mc = m + cw
        Bm = (0.0 * mc, -r[2] * mc, r[1] * mc,          # [r] (m + cw)
              r[2] * mc, 0.0 * mc, -r[0] * mc,
              -r[1] * mc, r[0] * mc, 0.0 * mc)
        Mm = (mc, 0.0, 0.0, 0.0, mc, 0.0, 0.0, 0.0, mc)
        # velocity-product bias: N_b = w x I_c w + m r x (w x (w x r)), F_b = m w x (w x r)
        wx, wy, wz = _get3(W, g + G_WM, ln)
        w = (wx, wy, wz)
        icp = m * seg * seg / 12.0
        wd = wx * dx + wy * dy + wz * dz
        nb = _cross3(w, (icp * (wx - wd * dx) + ia * wd * dx,
                         icp * (wy - wd * dy) + ia * wd * dy,
                         icp * (wz - wd * dz) + ia * wd * dz))      # w x I_c w
        t4 = _cross3(w, _cross3(w, r))                               # w x (w x r)
        fbx, fby, fbz = m * t4[0], m * t4[1], m * t4[2]
        # external wrench about the joint: f_dist at the centre, f_end at the end
        fdx, fdy, fdz = _get3(W, g + G_FD, ln)
        fex, fey, fez = _get3(W, g + G_FE, ln)
        nex = r[1] * (fdz + 2.0 * fez) - r[2] * (fdy + 2.0 * fey)
        ney = r[2] * (fdx + 2.0 * fex) - r[0] * (fdz + 2.0 * fez)
        nez = r[0] * (fdy + 2.0 * fey) - r[1] * (fdx + 2.0 * fex)
        nbx = nb[0] + r[1] * fbz - r[2] * fby
        nby = nb[1] + r[2] * fbx - r[0] * fbz
        nbz = nb[2] + r[0] * fby - r[1] * fbx
        _put3(W, g + G_PA, ln, (nbx - nex, nby - ney, nbz - nez))
        _put3(W, g + G_PL, ln, (fbx - fdx - fex, fby - fdy - fey, fbz - fdz - fez))
        _put9(W, g + G_JM, ln, Jm)
        _put9(W, g + G_BM, ln, Bm)
        _put9(W, g + G_MM, ln, Mm)


@njit_without_refcounts
def _take_contact(W, i, q):
    """Copy contact q of body i (its record's slot) where _contact_mass reads it (G_CQ)."""
    g = _rec(i)
    for ln in range(LANES):
        for k in range(6):
            W[_ix(g + G_CQ + k, ln)] = W[_ix(g + G_CT + 6 * q + k, ln)]
        W[_ix(g + G_CQ + 6, ln)] = q < W[_ix(g + G_NC, ln)]


@njit_without_refcounts
def _contact_mass(W, i):
    """
    Add body i's contact taken (_take_contact) as an added mass (GAMMA h^2 k + h c) n n^T.

    The contact (eqs. 7-10, applied explicitly as a force) is stiff for a light segment:
    its linearisation, F = -(k, c) n n^T (x, v) at the contact point, taken implicitly, so
    every joint up to the root feels it (the implicit damping of the articulated body; cf.
    the joints' own springs). Lanes whose segment has fewer contacts add nothing. (A loop
    of its own, for each slot some lane has, reading its slot at a fixed field: with the
    slots' loop inside the lanes', or the slot's fields at an offset LLVM does not know
    from the ones written, the lanes' loop was not vectorised.)
    """
    g = _rec(i)
    for ln in range(LANES):
        h = _get(W, g + G_H, ln)
        lv = _get(W, g + G_CQ + 2, ln) * _get(W, g + G_LEN, ln)
        Ri = _get9(W, g + G_RM, ln)
        nrm = _get3(W, g + G_CQ + 3, ln)
        cw = GAMMA * h * h * _get(W, g + G_CQ, ln) + h * _get(W, g + G_CQ + 1, ln)
        rn = _cross3((lv * Ri[2], lv * Ri[5], lv * Ri[8]), nrm)     # r x n
        Jm = _get9(W, g + G_JM, ln)
        Bm = _get9(W, g + G_BM, ln)
        Mm = _get9(W, g + G_MM, ln)
        held = _get(W, g + G_CQ + 6, ln) > 0.0
        _put9(W, g + G_JM, ln, _add3(Jm, _scaled_outer3(cw, rn, rn)) if held else Jm)
        _put9(W, g + G_BM, ln, _add3(Bm, _scaled_outer3(cw, rn, nrm)) if held else Bm)
        _put9(W, g + G_MM, ln, _add3(Mm, _scaled_outer3(cw, nrm, nrm)) if held else Mm)


@njit_without_refcounts
def _shape_spring(W, i):
    """
    Body i's shape spring: a couple -kg e_g, implicit (see step_chains), where kg > 0.

    Not vectorised (libm's atan2): run only when some lane has shape springs.
    """
    g = _rec(i)
    for ln in range(LANES):
        kg = _get(W, g + G_SK, ln)
        if kg <= 0.0:
            continue
        h = _get(W, g + G_H, ln)
        seg = _get(W, g + G_LEN, ln)
        m = _get(W, g + G_M, ln)
        ia = _get(W, g + G_IAX, ln)
        i_swing = m * seg * seg / 3.0 + ia
        theta = _get(W, g + G_TH, ln)
        Ri = _get9(W, g + G_RM, ln)
        dx, dy, dz = Ri[2], Ri[5], Ri[8]
        sx, sy, sz = _get3(W, g + G_SD, ln)
        sd = _apply3(_get9(W, G_RM, ln), sx, sy, sz)     # under the head at mid-step
        gx = sd[1] * dz - sd[2] * dy                     # sd x d
        gy = sd[2] * dx - sd[0] * dz
        gz = sd[0] * dy - sd[1] * dx
        sn = sqrt(gx * gx + gy * gy + gz * gz)
        ang = atan2(sn, sd[0] * dx + sd[1] * dy + sd[2] * dz)
        gg = ang / sn if sn > 1e-15 else 0.0
        ox, oy, oz = _get3(W, g + G_OM, ln)
        hx, hy, hz = _get3(W, G_OM, ln)                   # the head's turn
        qx, qy, qz = ox - hx, oy - hy, oz - hz
        qd = qx * dx + qy * dy + qz * dz
        qx, qy, qz = qx - qd * dx, qy - qd * dy, qz - qd * dz     # across the rod
        bg = h * h * kg / i_swing
        dg = GAMMA * UNRESOLVED_DAMPING * (bg / (1.0 + bg)) ** 4 * h * kg
        vg = (GAMMA - theta) * h * kg + dg
        pa0, pa1, pa2 = _get3(W, g + G_PA, ln)
        _put3(W, g + G_PA, ln, (pa0 + (kg * gg * gx + vg * qx),
                                pa1 + (kg * gg * gy + vg * qy),
                                pa2 + (kg * gg * gz + vg * qz)))
        cg = GAMMA * h * h * kg + h * dg
        _put9(W, g + G_JM, ln, _add3(_get9(W, g + G_JM, ln), (
            cg * (1.0 - dx * dx), -cg * dx * dy, -cg * dx * dz,
            -cg * dx * dy, cg * (1.0 - dy * dy), -cg * dy * dz,
            -cg * dx * dz, -cg * dy * dz, cg * (1.0 - dz * dz))))


@njit_without_refcounts
def _joint_rotation(W, i):
    """Joint i's rotation from its rest at mid-step, and its bend's sine."""
    g = _rec(i)
    p = g - SEG_FIELDS
    for ln in range(LANES):
        S = joint_rotation_of(_get9(W, p + G_RM, ln), _get9(W, g + G_REST, ln),
                              _get9(W, g + G_RM, ln))
        _put9(W, g + G_SJ, ln, S)
        _put(W, g + G_ST, ln, sqrt(S[2] * S[2] + S[5] * S[5]))


@njit_without_refcounts
def _bend_angles(W, i):
    """Joint i's bend angle, by libm's atan2 (a scalar pass between two vector loops)."""
    g = _rec(i)
    for ln in range(LANES):
        _put(W, g + G_T, ln, atan2(_get(W, g + G_ST, ln), _get(W, g + G_SJ + 8, ln)))


@njit_without_refcounts
def _joint(W, i, has_child):
    """Joint i of the backward pass: D^-1, U, u, and what its parent sees of it and beyond."""
    g = _rec(i)
    p = g - SEG_FIELDS
    for ln in range(LANES):
        h = _get(W, g + G_H, ln)
        seg = _get(W, g + G_LEN, ln)
        m = _get(W, g + G_M, ln)
        ia = _get(W, g + G_IAX, ln)
        i_swing = m * seg * seg / 3.0 + ia          # the rod's swing about its joint
        theta = _get(W, g + G_TH, ln)
        Jm = _get9(W, g + G_JM, ln)
        Bm = _get9(W, g + G_BM, ln)
        Mm = _get9(W, g + G_MM, ln)
        pa0, pa1, pa2 = _get3(W, g + G_PA, ln)
        pl0, pl1, pl2 = _get3(W, g + G_PL, ln)
        if has_child:
            # plus the child's articulated inertia and bias, already moved to this joint
            Jm = _add3(Jm, _get9(W, g + G_CA, ln))
            Bm = _add3(Bm, _get9(W, g + G_CB, ln))
            Mm = _add3(Mm, _get9(W, g + G_CM, ln))
            ca = _get3(W, g + G_CPA, ln)
            cl = _get3(W, g + G_CPL, ln)
            pa0 += ca[0]
            pa1 += ca[1]
            pa2 += ca[2]
            pl0 += cl[0]
            pl1 += cl[1]
            pl2 += cl[2]
        # ball joint i: spring and damper on the relative rotation, implicit part c
        Ri = _get9(W, g + G_RM, ln)
        dx, dy, dz = Ri[2], Ri[5], Ri[8]
        e = bend_deviation_at(_get9(W, g + G_SJ, ln), _get3(W, g + G_OFF, ln),
                              _get(W, g + G_T, ln))
        k = _get(W, g + G_K, ln)
        dd = _get(W, g + G_D, ln)
        # the implicit spring and damper work from the start-of-step velocities (the
        # head's record holds its turn)
        ox, oy, oz = _get3(W, g + G_OM, ln)
        px, py, pz = _get3(W, p + G_OM, ln)
        rwx, rwy, rwz = ox - px, oy - py, oz - pz
        # numerical damping of modes the step cannot resolve, b = h^2 k / I of the joint:
        # across the rod its swing inertia, along it the (tiny) twist inertia
        bs = h * h * k / i_swing
        bt = h * h * k / ia
        dp = GAMMA * UNRESOLVED_DAMPING * (bs / (1.0 + bs)) ** 4 * h * k
        dt_ = GAMMA * UNRESOLVED_DAMPING * (bt / (1.0 + bt)) ** 4 * h * k
        # the spring at its deviation predicted GAMMA h ahead, -k (e + GAMMA h w_rel+):
        # the drift before the kick supplied theta h w_rel of it, this the rest, across
        # the rod (stable when the substep count changes: see the module text)
        sp = (GAMMA - theta) * h * k
        da = dd + dp + sp                    # across the rod
        rd = (rwx * dx + rwy * dy + rwz * dz) * (dt_ - dp - sp)
        tqx = -k * (Ri[0] * e[0] + Ri[1] * e[1] + Ri[2] * e[2]) - da * rwx - rd * dx
        tqy = -k * (Ri[3] * e[0] + Ri[4] * e[1] + Ri[5] * e[2]) - da * rwy - rd * dy
        tqz = -k * (Ri[6] * e[0] + Ri[7] * e[1] + Ri[8] * e[2]) - da * rwz - rd * dz
        # the damping is implicit too: D gets h times the damping (anisotropic)
        cj = GAMMA * h * h * k + h * (dd + dp)
        ct = h * (dt_ - dp)
        d01, d02, d12 = Jm[1] + ct * dx * dy, Jm[2] + ct * dx * dz, Jm[5] + ct * dy * dz
        Sm = _without_twist(_inverse_sym3((Jm[0] + cj + ct * dx * dx, d01, d02,
                                           d01, Jm[4] + cj + ct * dy * dy, d12,
                                           d02, d12, Jm[8] + cj + ct * dz * dz)),
                            dx, dy, dz)
        _put9(W, g + G_DI, ln, Sm)
        _put9(W, g + G_UA, ln, Jm)
        _put9(W, g + G_UB, ln, Bm)
        u = (tqx - pa0, tqy - pa1, tqz - pa2)
        _put3(W, g + G_U, ln, u)
        # apparent inertia through the joint: I^a = I^A - U D^-1 U^T, U = [J; B^T]; the
        # root's parent, the head, takes it and keeps nothing of it
        Aa = _sub3(Jm, _mul3(Jm, _mul3(Sm, Jm)))
        SB = _mul3(Sm, Bm)
        Ba = _sub3(Bm, _mul3(Jm, SB))
        Ma = _sub3(Mm, _mul3(_transpose3(Bm), SB))
        # bias: p^a = p^A + I^a c + U D^-1 u, c = [0; w_p x (w_p x a_p)] (a_p: parent rod)
        lp = _get(W, p + G_LEN, ln)
        Rq = _get9(W, p + G_RM, ln)
        ax, ay, az = lp * Rq[2], lp * Rq[5], lp * Rq[8]
        wx, wy, wz = _get3(W, p + G_WM, ln)
        cx, cy, cz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
        cx, cy, cz = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx
        y0, y1, y2 = _apply3(Sm, u[0], u[1], u[2])
        qa0, qa1, qa2 = _apply_both3(Ba, (cx, cy, cz), Jm, (y0, y1, y2))
        ql0, ql1, ql2 = _apply_both3(Ma, (cx, cy, cz), _transpose3(Bm), (y0, y1, y2))
        qa0, qa1, qa2 = pa0 + qa0, pa1 + qa1, pa2 + qa2
        ql0, ql1, ql2 = pl0 + ql0, pl1 + ql1, pl2 + ql2
        # move to the parent's joint, a_p back along the parent rod:
        # A' = A - B[a] + [a]B^T - [a]M[a], B' = B + [a]M, M' = M, p'_ang = p_ang + a x p_lin
        Ka = (0.0, -az, ay, az, 0.0, -ax, -ay, ax, 0.0)
        KM = _mul3(Ka, Ma)
        Ap = _sub3(_add3(_sub3(Aa, _mul3(Ba, Ka)), _mul3(Ka, _transpose3(Ba))),
                   _mul3(KM, Ka))
        _put9(W, p + G_CA, ln, Ap)
        _put9(W, p + G_CB, ln, _add3(Ba, KM))
        _put9(W, p + G_CM, ln, Ma)
        _put3(W, p + G_CPA, ln, (qa0 + ay * ql2 - az * ql1, qa1 + az * ql0 - ax * ql2,
                                 qa2 + ax * ql1 - ay * ql0))
        _put3(W, p + G_CPL, ln, (ql0, ql1, ql2))


@njit_without_refcounts
def _accelerations(W, i):
    """Joint i of the forward pass: q'' = D^-1 (u - J alpha_p - B a_p), root to tip."""
    g = _rec(i)
    p = g - SEG_FIELDS
    for ln in range(LANES):
        ax_, ay_, az_ = _get3(W, p + G_AL, ln)
        lx, ly, lz = _get3(W, g + G_LA, ln)       # (the root's: the head's motion there)
        if i > 0:
            lx, ly, lz = _get3(W, p + G_LA, ln)
            lp = _get(W, p + G_LEN, ln)
            Rq = _get9(W, p + G_RM, ln)
            bx, by, bz = lp * Rq[2], lp * Rq[5], lp * Rq[8]
            wx, wy, wz = _get3(W, p + G_WM, ln)
            cx = wy * bz - wz * by
            cy = wz * bx - wx * bz
            cz = wx * by - wy * bx
            lx += ay_ * bz - az_ * by + wy * cz - wz * cy
            ly += az_ * bx - ax_ * bz + wz * cx - wx * cz
            lz += ax_ * by - ay_ * bx + wx * cy - wy * cx
        y0, y1, y2 = _apply_both3(_get9(W, g + G_UA, ln), (ax_, ay_, az_),
                                  _get9(W, g + G_UB, ln), (lx, ly, lz))
        u0, u1, u2 = _get3(W, g + G_U, ln)
        a0, a1, a2 = _apply3(_get9(W, g + G_DI, ln), u0 - y0, u1 - y1, u2 - y2)
        _put3(W, g + G_AL, ln, (a0 + ax_, a1 + ay_, a2 + az_))
        _put3(W, g + G_LA, ln, (lx, ly, lz))


@njit_without_refcounts
def _kick_turn(W, i):
    """Segment i's kick, and the turn of the rest of its drift."""
    g = _rec(i)
    for ln in range(LANES):
        h = _get(W, g + G_H, ln)
        ox, oy, oz = _get3(W, g + G_OM, ln)
        ax, ay, az = _get3(W, g + G_AL, ln)
        wx = ox + h * ax
        wy = oy + h * ay
        wz = oz + h * az
        _put3(W, g + G_WN, ln, (wx, wy, wz))
        f = (1.0 - _get(W, g + G_TH, ln)) * h                     # the rest of the drift
        _put_turn(W, g, ln, (f * wx, f * wy, f * wz))


@njit_without_refcounts
def _drift_to_end(W, i):
    """Turn segment i's frame by the rest of its drift; its end, before the guard."""
    g = _rec(i)
    p = g - SEG_FIELDS
    for ln in range(LANES):
        Rn = _orthonormalized(_mul3(_turn(W, g, ln), _get9(W, g + G_RM, ln)))
        seg = _get(W, g + G_LEN, ln)
        px, py, pz = _get3(W, p + G_E, ln)
        _put9(W, g + G_RN, ln, Rn)
        _put3(W, g + G_E, ln, (px + seg * Rn[2], py + seg * Rn[5], pz + seg * Rn[8]))


@njit_without_refcounts
def _place(W, i):
    """Segment i's frame without twist, its spin taken out, its end's velocity and rate."""
    g = _rec(i)
    p = g - SEG_FIELDS
    for ln in range(LANES):
        Rn = _get9(W, g + G_RN, ln)
        # 2-DOF joints: a pure bend from the parent (already placed), no twist
        Rf = twist_free_rotation(_get9(W, p + G_RF, ln), _get9(W, g + G_REST, ln), Rn)
        # ... and no spin about the rod relative to its parent (it moves no vertex)
        pw = _get3(W, p + G_WF, ln)
        wx, wy, wz = _without_relative_spin(_get3(W, g + G_WN, ln), pw, (Rn[2], Rn[5], Rn[8]))
        seg = _get(W, g + G_LEN, ln)
        bx, by, bz = seg * Rn[2], seg * Rn[5], seg * Rn[8]
        vx, vy, vz = _get3(W, p + G_V, ln)
        vx += wy * bz - wz * by
        vy += wz * bx - wx * bz
        vz += wx * by - wy * bx
        qx, qy, qz = wx - pw[0], wy - pw[1], wz - pw[2]
        _put(W, g + G_RATE, ln, seg * sqrt(qx * qx + qy * qy + qz * qz))
        _put9(W, g + G_RF, ln, Rf)
        _put3(W, g + G_WF, ln, (wx, wy, wz))
        _put3(W, g + G_V, ln, (vx, vy, vz))


@njit_without_refcounts
def _load_segment(W, lanes, i, state, strands, forces, shaped):
    """Copy what the phases read of segment i of each lane's strand into W; return slots."""
    R, omega, alpha_prev, rest_rel = state.R, state.omega, state.alpha, state.rest_rel
    kj, i_ax, shape_k = state.k, state.inertia_axial, state.shape_k
    offset, dj, shape_dir = state.offset, state.d, state.shape_dir
    f_dist, f_end, contact = forces.f_dist, forces.f_end, forces.contact
    length, mass = strands.length, strands.mass
    g = _rec(i)
    slots = 0                   # the most contacts a lane's segment i has
    for ln in range(LANES):
        s = lanes[ln]
        for a in range(3):
            for b in range(3):
                W[_ix(g + G_R0 + 3 * a + b, ln)] = R[s, i, a, b]
                W[_ix(g + G_REST + 3 * a + b, ln)] = rest_rel[s, i, a, b]
            W[_ix(g + G_OM + a, ln)] = omega[s, i, a]
            W[_ix(g + G_ALP + a, ln)] = alpha_prev[s, i, a]
            W[_ix(g + G_FD + a, ln)] = f_dist[s, i, a]
            W[_ix(g + G_FE + a, ln)] = f_end[s, i, a]
            W[_ix(g + G_OFF + a, ln)] = offset[s, i, a]
            if shaped:
                W[_ix(g + G_SD + a, ln)] = shape_dir[s, i, a]
        W[_ix(g + G_LEN, ln)] = length[s, i]
        W[_ix(g + G_M, ln)] = mass[s, i]
        W[_ix(g + G_K, ln)] = kj[s, i]
        W[_ix(g + G_IAX, ln)] = i_ax[s, i]
        W[_ix(g + G_SK, ln)] = shape_k[s, i]
        W[_ix(g + G_D, ln)] = dj[s, i]
        W[_ix(g + G_H, ln)] = W[_ix(G_H, ln)]
        n_c = 0
        for q in range(CONTACT_SLOTS):
            slot = q * CONTACT_FIELDS
            kc = contact[s, i, slot + CONTACT_K]
            cc = contact[s, i, slot + CONTACT_C]
            if kc + cc <= 0.0:
                break
            f = g + G_CT + 6 * q
            W[_ix(f, ln)] = kc
            W[_ix(f + 1, ln)] = cc
            W[_ix(f + 2, ln)] = contact[s, i, slot + CONTACT_LEVER]
            W[_ix(f + 3, ln)] = contact[s, i, slot + CONTACT_NX]
            W[_ix(f + 4, ln)] = contact[s, i, slot + CONTACT_NY]
            W[_ix(f + 5, ln)] = contact[s, i, slot + CONTACT_NZ]
            n_c += 1
        W[_ix(g + G_NC, ln)] = n_c
        slots = max(slots, n_c)
    return slots


@njit_without_refcounts
def _lane_to_chain(W, ln, n_seg, sc):
    """Copy lane ln's articulated pass (D^-1, U, alpha) into the per-chain scratch sc."""
    for i in range(n_seg):
        g = _rec(i)
        for a in range(3):
            for b in range(3):
                sc.Dinv[i, a, b] = W[_ix(g + G_DI + 3 * a + b, ln)]
                sc.U_A[i, a, b] = W[_ix(g + G_UA + 3 * a + b, ln)]
                sc.U_B[i, a, b] = W[_ix(g + G_UB + 3 * a + b, ln)]
            sc.alpha[i, a] = W[_ix(g + G_AL + a, ln)]


@njit_without_refcounts
def _guard_lane(W, ln, i, start, seg, spheres, mask, sag_by_height, sc):
    """
    Guard lane ln's segment i (forces.guard_segment); return whether it moved the end.

    Turns the rod minimally onto the guarded direction, and keeps where the end was moved
    (sc.l_guarded, sc.l_gnrm) for the impulse that stops its inward motion.
    """
    g = _rec(i)
    px, py, pz = start
    ex, ey, ez = _get3(W, g + G_E, ln)
    gx, gy, gz, moved = guard_segment((px, py, pz), (ex, ey, ez), seg, spheres, mask,
                                      GUARD_LIFT, sag_by_height)
    if not moved:
        return False
    Rn = _get9(W, g + G_RN, ln)
    ox, oy, oz = Rn[2], Rn[5], Rn[8]
    nx, ny, nz = (gx - px) / seg, (gy - py) / seg, (gz - pz) / seg
    ax, ay, az = oy * nz - oz * ny, oz * nx - ox * nz, ox * ny - oy * nx
    sn = sqrt(ax ** 2 + ay ** 2 + az ** 2)
    cs = ox * nx + oy * ny + oz * nz
    if sn > 1e-15:
        ang = np.arctan2(sn, cs)
        turn = rotation_exp(ax / sn * ang, ay / sn * ang, az / sn * ang)
        _put9(W, g + G_RN, ln, _orthonormalized(_mul3(turn, Rn)))
    # the velocity is mended after the chain is placed, by an impulse through the
    # articulated inertias (_stop_inward_motion); changing this rod's angular velocity
    # alone moved every vertex beyond with it and pumped energy into draped strands
    # (hanging scene: 19 mm from MuJoCo)
    gn = sqrt((gx - ex) ** 2 + (gy - ey) ** 2 + (gz - ez) ** 2)
    if gn > 1e-15:
        sc.l_guarded[ln, i] = True
        sc.l_gnrm[ln, i, 0] = (gx - ex) / gn
        sc.l_gnrm[ln, i, 1] = (gy - ey) / gn
        sc.l_gnrm[ln, i, 2] = (gz - ez) / gn
    _put3(W, g + G_E, ln, (gx, gy, gz))
    return True


@njit_without_refcounts
def _step_lanes(state,
                strands,
                forces,
                head,
                base,
                bodies,
                collide,
                timing,
                sc,
                n_valid):
    """
    Step the strands sc.lanes[:n_valid] together (the other lanes repeat the last one).

    Returns (the guard's moves, the fastest end speed about its start). See step_chains.
    """
    R, omega, alpha_prev = state.R, state.omega, state.alpha
    pos, pos_prev, vel, length = strands.pos, strands.pos_prev, strands.vel, strands.length
    roots, root_vel, root_acc = base
    spheres, masks = bodies.spheres, bodies.masks
    strand_h, strand_t = timing
    W, lanes = sc.W, sc.lanes
    n_seg = length.shape[1]
    spin = head.turn
    shaped = False
    for ln in range(LANES):
        s = lanes[ln]
        W[_ix(G_H, ln)] = strand_h[s]
        for i in range(n_seg):
            if state.shape_k[s, i] > 0.0:
                shaped = True
    # ---------------- part of the drift: the configuration at mid-step (Stormer-Verlet).
    # A joint too stiff for the step (b = h^2 k / I >> 1) takes its force at the start
    # instead (symplectic Euler), and its mid-step velocity prediction fades likewise.
    for i in range(n_seg):
        sc.slots[i] = _load_segment(W, lanes, i, state, strands, forces, shaped)
        _drift_turn(W, i)
        _take_rotation_coefficients(W, i)
        _drift_to_mid(W, i)
    # The head between its poses (it turns at head.turn over the step; head.R is its pose
    # at the step's end, head.t): the base of the root joint where the strand's
    # configuration is, at mid-step, and at the end of its own step; the head's record
    Rh = _load3(head.R)
    for ln in range(LANES):
        s = lanes[ln]
        lag = head.t - strand_t[s]
        _put9(W, G_RF, ln, _mul3(rotation_exp(-lag * spin[0], -lag * spin[1],
                                              -lag * spin[2]), Rh))
        lag += (1.0 - W[_ix(_rec(0) + G_TH, ln)]) * W[_ix(G_H, ln)]
        _put9(W, G_RM, ln, _mul3(rotation_exp(-lag * spin[0], -lag * spin[1],
                                              -lag * spin[2]), Rh))
        _put3(W, G_OM, ln, (spin[0], spin[1], spin[2]))
        _put3(W, G_WF, ln, (spin[0], spin[1], spin[2]))
        _put3(W, G_WM, ln, (0.0, 0.0, 0.0))
        _put3(W, G_AL, ln, (head.alpha[0], head.alpha[1], head.alpha[2]))
        _put3(W, _rec(0) + G_LA, ln, (root_acc[s, 0], root_acc[s, 1], root_acc[s, 2]))
        _put3(W, G_E, ln, (roots[s, 0], roots[s, 1], roots[s, 2]))
        _put3(W, G_V, ln, (root_vel[s, 0], root_vel[s, 1], root_vel[s, 2]))
        _put(W, G_LEN, ln, 0.0)
    # ---------------- backward pass: articulated inertias, tip to root; forward pass
    for i in range(n_seg - 1, -1, -1):
        _body_inertia(W, i, state.air)
        for q in range(sc.slots[i]):
            _take_contact(W, i, q)
            _contact_mass(W, i)
        if shaped:
            _shape_spring(W, i)
        _joint_rotation(W, i)
        _bend_angles(W, i)
        _joint(W, i, i < n_seg - 1)
    for i in range(n_seg):
        _accelerations(W, i)
    # the next step predicts its mid-step velocities from these (_drift_turn): the
    # accelerations of the forces, without the contact impulses below. With them, the
    # step after a strand hit the head extrapolated the impact's 1e5 rad/s^2 into its
    # velocity-product terms and gave the strand energy (hanging scene at 1/960 s: 0.0087
    # m g L in one step, a sixth of its motion; -0.0011 without)
    for ln in range(n_valid):
        s = lanes[ln]
        for i in range(n_seg):
            for a in range(3):
                alpha_prev[s, i, a] = W[_ix(_rec(i) + G_AL + a, ln)]
    # ---------------- contacts before the drift, strand by strand
    if collide:
        contact = forces.contact
        for ln in range(n_valid):
            s = lanes[ln]
            touching = False
            for i in range(n_seg):
                if contact[s, i, CONTACT_K] + contact[s, i, CONTACT_C] > 0.0:
                    touching = True
                    break
            if not touching:
                continue
            for i in range(n_seg):
                for a in range(3):
                    for b in range(3):
                        R[s, i, a, b] = W[_ix(_rec(i) + G_RM + 3 * a + b, ln)]
            _lane_to_chain(W, ln, n_seg, sc)
            _speculative_contacts(s,
                                  contact,
                                  (R, omega, length),
                                  (roots, root_vel),
                                  head,
                                  spheres,
                                  (sc.Dinv, sc.U_A, sc.U_B),
                                  (sc.u_imp, sc.rc_imp, sc.c_seg, sc.c_lever, sc.c_nrm,
                                   sc.c_bound, sc.c_load, sc.c_lam, sc.c_fric, sc.c_dw,
                                   sc.c_dvn, sc.c_dwb, sc.c_K),
                                  sc.alpha,
                                  W[_ix(G_H, ln)],
                                  state.friction)
            for i in range(n_seg):
                for a in range(3):
                    W[_ix(_rec(i) + G_AL + a, ln)] = sc.alpha[i, a]
    # ---------------- the kick, the rest of the drift, the guard, the placed chain
    for ln in range(n_valid):
        s = lanes[ln]
        for a in range(3):
            pos_prev[s, 0, a] = pos[s, 0, a]
            pos[s, 0, a] = roots[s, a]
            vel[s, 0, a] = root_vel[s, a]
    guards = 0
    guarded = False
    for i in range(n_seg):
        g = _rec(i)
        _kick_turn(W, i)
        _take_rotation_coefficients(W, i)
        _drift_to_end(W, i)
        if collide:
            for ln in range(n_valid):
                s = lanes[ln]
                sc.l_guarded[ln, i] = False
                if masks[s] != 0 and _guard_lane(W, ln, i, _get3(W, g - SEG_FIELDS + G_E, ln),
                                                 length[s, i], spheres, masks[s],
                                                 state.sag_by_height, sc):
                    guards += 1
                    guarded = True
        _place(W, i)
        for ln in range(n_valid):
            s = lanes[ln]
            for a in range(3):
                for b in range(3):
                    R[s, i, a, b] = W[_ix(g + G_RF + 3 * a + b, ln)]
                omega[s, i, a] = W[_ix(g + G_WF + a, ln)]
                pos_prev[s, i + 1, a] = pos[s, i + 1, a]
                pos[s, i + 1, a] = W[_ix(g + G_E + a, ln)]
                vel[s, i + 1, a] = W[_ix(g + G_V + a, ln)]
    if guarded:
        for ln in range(n_valid):
            n_guarded = 0
            for i in range(n_seg):
                sc.guarded[i] = sc.l_guarded[ln, i]
                n_guarded += sc.guarded[i]
                for a in range(3):
                    sc.g_nrm[i, a] = sc.l_gnrm[ln, i, a]
            if n_guarded == 0:
                continue
            _rigid_articulated_inertias(lanes[ln], R, length, strands.mass,
                                        state.inertia_axial, (sc.Dinv, sc.U_A, sc.U_B))
            _stop_inward_motion(lanes[ln],
                                (sc.guarded, sc.g_nrm),
                                (R, omega, length),
                                (roots, root_vel),
                                head,
                                (sc.Dinv, sc.U_A, sc.U_B),
                                (sc.u_imp, sc.dw, sc.rc_imp, sc.lam_imp),
                                vel)
    top = 0.0
    for ln in range(n_valid):
        for i in range(n_seg):
            rate = W[_ix(_rec(i) + G_RATE, ln)]
            if rate > top:                          # (NaN never counts)
                top = rate
    return guards, top


@njit_without_refcounts
def step_chains(state,
                strands,
                forces,
                head,
                roots,
                root_vel,
                root_acc,
                bodies,
                collide,
                timing,
                stats,
                scratch):
    """
    Advance each strand's chain by its own step (articulated-body algorithm).

    timing is (strand_h, strand_t): each strand's step (0: it waits) and when it ends.
    The strands that move are stepped LANES at a time (the last lanes of the last group
    repeat its last strand and are not written back); see the module text and LANES.

    Reads the shared per-segment forces (world), the head's motion (base of every chain),
    writes the new orientations, angular velocities, vertices and vertex velocities. The
    position guard turns a segment out of a sphere, and a contact impulse stops its end's
    inward motion through the whole chain. Returns the segments updated.
    """
    strand_h = timing[0]
    n_s, n_seg = strands.length.shape
    lanes = scratch.lanes
    base = (roots, root_vel, root_acc)
    guards = 0
    top = 0.0
    updated = 0
    n = 0
    for s in range(n_s + 1):
        if s < n_s:
            if strand_h[s] <= 0.0:
                continue
            lanes[n] = s
            n += 1
            updated += n_seg
            if n < LANES:
                continue
        elif n == 0:
            break
        for ln in range(n, LANES):
            lanes[ln] = lanes[n - 1]
        moves, rate = _step_lanes(state, strands, forces, head, base, bodies, collide, timing,
                                  scratch, n)
        guards += moves
        if rate > top:
            top = rate
        n = 0
    stats[MAX_RATE] = top
    stats[GUARD_MOVES] += guards
    return updated


@njit_without_refcounts
def chain_step(state,
               strands,
               pos_mid,
               forces,
               bodies,
               head,
               attach,
               wind,
               springs,
               settings,
               step,
               counts,
               strand_h,
               strand_t,
               stats,
               scratch):
    """
    Take one whole step of the chains in one call: all of its substeps.

    The kernels the driver would otherwise call one by one per substep (see
    HairSimulator._simulate), without the Python between them: the roots and spheres
    placed with the head and the broad phase (once: the head's motion is the step's),
    then per substep the shared forces of eqs. 5 and 7-11 at each strand's mid-step
    configuration x + (own h / 2) v, the springs of 5.2 after the contacts, and
    step_chains. step is (t at the step's end, h, n substeps, whether the forces are taken
    at mid-step (forces_at_mid_step) or at the start); counts[s] <= n, and strand s moves
    by h / counts[s] at the substeps in which one of its own ends, waiting at the others
    (multirate_substep's schedule); strand_h and strand_t are scratch (n_strands,): each
    strand's step and the end of its own substep (the wind's time). springs is
    (StripSprings, SpringConstants). Returns (broad-phase checks, contacts, wall springs,
    segments updated), summed over the substeps.
    """
    t_end, h, n, mid_step = step
    checks = place_with_head(head, attach, bodies, settings.collisions, settings.broad_phase)
    pos, vel = strands.pos, strands.vel
    at_mid = Strands(pos_mid if mid_step else pos, strands.pos_prev, vel, strands.length,
                     strands.mass)
    n_s, n_v = pos.shape[0], pos.shape[1]
    contacts = walls = segments = 0
    for k in range(n):
        t = t_end - h + (k + 1) * h / n
        multirate_substep((t_end, h, n), k, counts, strand_h, strand_t)
        for s in range(n_s):
            if mid_step and strand_h[s] > 0.0:
                # each strand that moves at the middle of its own substep (the forces of
                # one that waits are neither taken nor read: strands joined by springs,
                # whose springs read them all, all move in every substep)
                half = 0.5 * (h / counts[s])
                for j in range(n_v):
                    for a in range(3):
                        pos_mid[s, j, a] = vel[s, j, a] * half + pos[s, j, a]
        # drag against still air too (ArticulatedSolver.still_air_drag), and no root
        # inertia: the base motion comes out of the dynamics
        external_forces(at_mid, attach.root_acc, settings.gravity, wind, True, t,
                        settings.drag_factor, settings.air_damping, False, forces,
                        (strand_h, strand_t))
        if not settings.collisions:      # (else reaction_constraint_forces clears it)
            clear_contact_record(forces.contact)
        else:
            contacts += reaction_constraint_forces(at_mid,
                                                   bodies,
                                                   settings.collision_stiffness,
                                                   settings.collision_damping,
                                                   True,
                                                   forces,
                                                   None,
                                                   strand_h,
                                                   DROPS_INWARD_INPUT,
                                                   CONTACT_FORCE_AT_Q)
        if settings.inter_strip and springs[0].pairs.shape[0] > 0:
            walls += strip_springs(at_mid, bodies.spheres[:settings.n_scalp], springs[0],
                                   springs[1], forces)
        segments += step_chains(state,
                                strands,
                                forces,
                                head,
                                attach.roots,
                                attach.root_vel,
                                attach.root_acc,
                                bodies,
                                settings.collisions,
                                (strand_h, strand_t),
                                stats,
                                scratch)
    return checks, contacts, walls, segments


# ------------------------------------------------------------------ set-up (numpy, once)
def frames_along(directions, first):
    """
    Return rotation matrices (..., n, 3, 3) whose z columns are `directions` (..., n, 3).

    Twist-free: each frame is its predecessor turned by the smallest rotation taking one
    direction to the next (parallel transport); the first starts from `first` (..., 3, 3)
    turned minimally onto the first direction.
    """
    d = np.asarray(directions, dtype=np.float64)
    out = np.empty(d.shape[:-1] + (3, 3))
    prev = np.asarray(first, dtype=np.float64)
    prev_z = prev[..., :, 2]
    for i in range(d.shape[-2]):
        out[..., i, :, :] = minimal_rotation(prev_z, d[..., i, :]) @ prev
        prev = out[..., i, :, :]
        prev_z = d[..., i, :]
    return out


def minimal_rotation(a, b):
    """Return the smallest rotations (..., 3, 3) taking unit vectors a to b (..., 3)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    v = np.cross(a, b)
    c = (a * b).sum(-1)
    s2 = (v * v).sum(-1)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    f = np.where(s2 > 1e-30, (1.0 - c) / np.where(s2 > 1e-30, s2, 1.0), 0.5)
    R = np.eye(3) + K + (K @ K) * f[..., None, None]
    # opposite directions: a half turn about any axis perpendicular to a
    flip = (c < -1.0 + 1e-12)
    if np.any(flip):
        af = a[flip]
        axis = np.cross(af, np.where(np.abs(af[..., :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        R[flip] = 2.0 * axis[..., :, None] * axis[..., None, :] - np.eye(3)
    return R


def joints_and_centres(frames, length):
    """Return each segment's start p_i and centre c_i (n_s, n_seg, 3), roots at the origin."""
    seg = frames[..., :, 2] * length[..., None]
    joints = np.concatenate([np.zeros_like(seg[:, :1]), np.cumsum(seg, axis=1)[:, :-1]], axis=1)
    return joints, joints + 0.5 * seg


def sum_beyond(x):
    """Return, along axis 1, each segment's sum over itself and every segment beyond it."""
    return np.cumsum(x[:, ::-1], axis=1)[:, ::-1]


def sag_free_offsets(frames, length, mass, k, gravity):
    """
    Return each joint's spring offset e0 (n_s, n_seg, 3, child frame) that holds the pose.

    frames: the modeled orientations (head frame, head upright). One recursive
    Newton-Euler pass (statics) gives the torque joint i must hold, tau_i = -sum over the
    segments beyond of (c_j - p_i) x m_j g; the spring -k R (e - e0) gives exactly that at
    the modeled pose (e = 0) with e0 = R^T tau / k. An offset, not a turned rest rotation:
    a soft joint may need more than half a turn of spring, which a rotation cannot hold.
    """
    joints, centres = joints_and_centres(frames, length)
    weight = mass[..., None] * np.asarray(gravity, dtype=np.float64)
    # moment of the weights beyond joint i about joint i: sum_j (c_j - p_i) x w_j
    moment_about_origin = sum_beyond(np.cross(centres, weight))
    tau = -(moment_about_origin - np.cross(joints, sum_beyond(weight)))
    e0 = np.zeros_like(tau)
    held = k > 0
    e0[held] = np.einsum('nji,nj->ni', frames[held], tau[held]) / k[held][:, None]
    return e0


def inertia_beyond(frames, length, mass):
    """
    Return each joint's inertia of everything beyond it about the joint (n_s, n_seg), kg m^2.

    The rods beyond joint i, at the pose, as sum_j m_j (|c_j - p_i|^2 + l_j^2 / 12): m l^2 / 3
    for the last rod, M L^2 / 3 for a straight strand at its root. A joint damper d_i =
    damping * this damps the swing of everything beyond the joint at the rate `damping`
    (1/s), the thesis model's meaning of the same parameter (gamma / I of eq. 1). With
    d = damping * m l^2 / 3 at every joint, a straight n-segment strand's swing about its
    root was damped n^3 times slower than its last segment's: the linear modes of a hanging
    9-segment, 25 cm chain decayed at 0.00-0.13/s, and after a head turn the shipped styles
    were still moving 12 s later (measured).
    """
    joints, centres = joints_and_centres(frames, length)
    m_cc = sum_beyond(mass * ((centres * centres).sum(-1) + length * length / 12.0))
    m_c = sum_beyond(mass[..., None] * centres)
    m = sum_beyond(mass)
    return m_cc - 2.0 * (m_c * joints).sum(-1) + m * (joints * joints).sum(-1)


def gravity_stiffness(frames, length, mass, gravity):
    """
    Return the Hessian of the chains' weight potential at a pose, (n_s, n_seg, n_seg, 3, 3).

    Coordinates: a small world rotation x_i at joint i turns everything beyond it about
    p_i. With C_k = sum over the segments beyond joint k of m_j (c_j - p_k) (centres c_j)
    and g the gravity vector, the potential -sum m_j g.c_j has the second derivatives
    H_ik = -(C_k g^T - (g.C_k) I) for i < k (H_ki its transpose) and
    H_kk = -((g C_k^T + C_k g^T) / 2 - (g.C_k) I): negative across a rod that stands up
    (the inverted pendulum), positive across one that hangs.
    """
    n_s, n_seg = length.shape
    joints, centres = joints_and_centres(frames, length)
    g = np.asarray(gravity, dtype=np.float64)
    # C_k = sum_{j >= k} m_j (c_j - p_k)
    C = sum_beyond(mass[..., None] * centres) - sum_beyond(mass)[..., None] * joints
    gC = (C @ g)[..., None, None] * np.eye(3)
    across = -(np.einsum('nka,b->nkab', C, g) - gC)
    own = -(0.5 * (np.einsum('a,nkb->nkab', g, C) + np.einsum('nka,b->nkab', C, g)) - gC)
    H = np.zeros((n_s, n_seg, n_seg, 3, 3))
    for k in range(n_seg):
        H[:, :k, k] = across[:, k, None]
        H[:, k, :k] = np.swapaxes(across[:, k, None], -1, -2)
        H[:, k, k] = own[:, k]
    return H


def stiffness_to_hold(frames, length, mass, k, gravity):
    """
    Return per strand by what factor its joint stiffness must grow for the pose to be stable.

    At the pose (an equilibrium: sag-free offsets) the potential's Hessian in the joints'
    swing coordinates (each joint's two axes across its rod; the joints do not twist) is
    K + H_g: the springs k_i I (e = 0 there, where the log map is exact) and the weight's
    gravity_stiffness. A strand that stands up against gravity can make it indefinite:
    the style is an equilibrium it falls off at the first touch (measured: after a 2 degree
    head turn, the side strands of thesis_long went 25 cm away and stayed there). The
    factor is the largest eigenvalue of -K^-1/2 H_g K^-1/2, which scaling K must exceed.
    """
    n_s, n_seg = length.shape
    need = np.zeros(n_s)
    springs = np.flatnonzero((k > 0.0).all(axis=1) & np.isfinite(k).all(axis=1))
    if n_seg == 0:
        return need
    # a few strands at a time: the Hessians take n_seg^2 * 72 bytes a strand
    chunk = max(1, STABILITY_CHUNK_BYTES // (72 * n_seg * n_seg))
    for start in range(0, len(springs), chunk):
        sel = springs[start:start + chunk]
        f = frames[sel]
        H = gravity_stiffness(f, length[sel], mass[sel], gravity)
        B = f[..., :, :2]
        # swing[n, i, p, k, q] = B[n, i]^T H[n, i, k] B[n, k], as batched 3 x 3 products
        # (one einsum over all seven indices took 9.3 ms of a 20 ms switch to this model
        # for thesis_long, these 1.3; 2026-11-30)
        BtH = np.matmul(np.swapaxes(B, -1, -2)[:, :, None], H)
        swing = np.matmul(BtH, B[:, None]).transpose(0, 1, 3, 2, 4)
        swing = swing.reshape(-1, 2 * n_seg, 2 * n_seg)
        inv_sqrt_k = np.repeat(k[sel], 2, axis=1) ** -0.5
        need[sel] = np.linalg.eigvalsh(
            -swing * inv_sqrt_k[:, :, None] * inv_sqrt_k[:, None, :])[:, -1]
    return need


def chain_scratch(n_seg):
    """
    Return the scratch arrays step_chains works in for strands of n_seg segments.

    Made once per solver and reused every step, so that step_chains allocates nothing
    and runs without reference counts (hair_sim.kernels). Every array is written before
    it is read, for each strand.
    """
    n_c = 2 * n_seg * CONTACT_SLOTS          # the speculative contacts, at most
    return ChainScratch(
        W=np.zeros((n_seg + 1) * SEG_FIELDS * LANES),  # the lanes (see LANES)
        lanes=np.zeros(LANES, dtype=np.int64),  # the strand in each lane
        slots=np.zeros(n_seg, dtype=np.int64),  # the most contacts a lane's segment has
        l_guarded=np.zeros((LANES, n_seg), dtype=np.bool_),  # per lane: the guard moved
        l_gnrm=np.zeros((LANES, n_seg, 3)),  # ... the end, along l_gnrm
        Dinv=np.zeros((n_seg, 3, 3)),  # one lane's articulated pass, for its contacts
        U_A=np.zeros((n_seg, 3, 3)),
        U_B=np.zeros((n_seg, 3, 3)),
        alpha=np.zeros((n_seg, 3)),
        guarded=np.zeros(n_seg, dtype=np.bool_),  # contacts of this step: the guard moved
        g_nrm=np.zeros((n_seg, 3)),  # ... the end, along g_nrm
        u_imp=np.zeros((n_seg, 3)),
        dw=np.zeros((n_seg, 3)),
        rc_imp=np.zeros(3),
        lam_imp=np.zeros(n_seg),
        c_seg=np.zeros(n_c, dtype=np.int64),  # the speculative contacts
        c_lever=np.zeros(n_c),
        c_nrm=np.zeros((n_c, 3)),
        c_bound=np.zeros(n_c),
        c_load=np.zeros(n_c),
        c_lam=np.zeros(n_c),  # normal impulses
        c_fric=np.zeros((n_c, 3)),  # friction impulses
        c_dw=np.zeros((n_c, n_seg, 3)),  # their normal responses
        c_dvn=np.zeros(n_c),
        c_dwb=np.zeros((n_c, 3, n_seg, 3)),  # their responses to impulses along x, y, z
        c_K=np.zeros((n_c, 3, 3)),  # ... at the point (rows: x, y, z; K[c, 0, 0] < 0: none)
    )


class ArticulatedSolver:
    """Thin class over step_chains: orientations, angular velocities, joint constants."""

    name = 'articulated'
    root_inertia = False            # the base motion comes out of the dynamics
    # drag on the velocity relative to the air, still air too: without it the light tips
    # of a chain whipped at 300-400 rad/s under violent head motion and the step diverged
    still_air_drag = True
    holds_modeled_walls = True      # type-2 springs act only nearer than the modeled pose
    retries_diverged_steps = True   # a step that blows up is taken again, finer
    uses_contacts = True         # contacts are folded into the articulated inertia
    forces_at_mid_step = True    # Stormer-Verlet: the forces at x + (h / 2) v
    contact_damping_rate = CONTACT_DAMPING_RATE   # 1/s, times the mass per metre
    fused = False                # (not one call per substep: see whole_step)
    whole_step = True            # all of a step's substeps in one call (chain_step)
    springs_before_contacts = False  # contacts first (the chain takes them implicitly)
    drops_inward_input = DROPS_INWARD_INPUT  # the contact impulses bear what presses
    contact_force_at_q = CONTACT_FORCE_AT_Q  # eq. 10 acts at Q, on to the parents

    def __init__(self, sim):
        n_s, n_seg = sim.length.shape
        self.R = np.zeros((n_s, n_seg, 3, 3))
        self.omega = np.zeros((n_s, n_seg, 3))
        self.alpha = np.zeros((n_s, n_seg, 3))
        # the modeled frames, twist-free from the head frame (head upright)
        self.modeled = frames_along(sim.modeled_dir, np.broadcast_to(np.eye(3), (n_s, 3, 3)))
        # each joint's rest: the modeled child frame seen from the modeled parent frame
        parents = np.concatenate([np.broadcast_to(np.eye(3), (n_s, 1, 3, 3)),
                                  self.modeled[:, :-1]], axis=1)
        self.rest_rel = np.ascontiguousarray(np.swapaxes(parents, -1, -2) @ self.modeled)
        self.scratch = chain_scratch(n_seg)
        self._swings = np.zeros(n_s)              # substeps_for's per-strand fastest swing
        self._strand_h = np.zeros(n_s)            # chain_step's per-substep steps
        self._strand_t = np.zeros(n_s)            # and the ends of the strands' own substeps
        self._step_call = CompiledCall(chain_step)
        self._energies_call = CompiledCall(strand_energies)
        self.placed = False                       # (R holds no pose yet)
        self.update_material(sim)

    def update_material(self, sim):
        """
        Recompute joint stiffness, damping, axial inertia and the sag-free offsets.

        Once the chain is placed (a change of the parameters), the joints' stiffness goes
        from the old to the new over MATERIAL_BLEND_S (relax_material; `blending`
        meanwhile), the offsets giving the new preload torques all along, and so do the
        shape springs (SHAPE_BLEND_FLOOR); the rest takes effect at once.
        """
        before = (self.k, self.offset, self.shape_k) if self.placed else None
        self._material(sim)
        self.k_target, self.offset_target = self.k, self.offset
        self.shape_k_target = self.shape_k
        self.blending = False
        if before is None or (np.array_equal(before[0], self.k)
                              and np.array_equal(before[1], self.offset)
                              and np.array_equal(before[2], self.shape_k)):
            return
        self._blend_from = before[0]
        self._shape_k_from = before[2]
        self._preload = self.k_target[..., None] * self.offset_target
        self._blend_left = MATERIAL_BLEND_S
        self.k, self.offset = before[0].copy(), np.zeros_like(self.offset_target)
        self.shape_k = before[2].copy()
        self._offsets_from_preload()
        self.blending = True

    def relax_material(self, h):
        """Take the joints' stiffness h seconds further to the new material's (smoothstep)."""
        if not self.blending:
            return
        self._blend_left -= h
        if self._blend_left <= 1e-9 * MATERIAL_BLEND_S:
            self._end_blend()
            return
        u = 1.0 - self._blend_left / MATERIAL_BLEND_S      # 0 -> 1
        w = u * u * (3.0 - 2.0 * u)                          # smoothstep: no jolt at the ends
        k_from, k_to = self._blend_from, self.k_target
        both = (k_from > 0.0) & (k_to > 0.0)
        ratio = np.divide(k_to, k_from, out=np.ones_like(k_to), where=both)
        self.k[:] = np.where(both, k_from * ratio ** w, k_from + (k_to - k_from) * w)
        # the shape springs geometrically too, from (or to) SHAPE_BLEND_FLOOR of the other
        # end where one end is 0
        s_from, s_to = self._shape_k_from, self.shape_k_target
        s_from = np.where(s_from > 0.0, s_from, SHAPE_BLEND_FLOOR * s_to)
        s_to = np.where(s_to > 0.0, s_to, SHAPE_BLEND_FLOOR * s_from)
        ratio = np.divide(s_to, s_from, out=np.ones_like(s_to), where=s_from > 0.0)
        self.shape_k[:] = s_from * ratio ** w
        self._offsets_from_preload()

    def _offsets_from_preload(self):
        """Set the offsets that give the new material's preload torques k e0 at today's k."""
        np.divide(self._preload, self.k[..., None], out=self.offset,
                  where=self.k[..., None] > 0.0)
        self.offset[self.k <= 0.0] = 0.0

    def _end_blend(self):
        """Put the joints at the new material's stiffness and offsets at once (placed anew)."""
        if self.blending:
            self.k, self.offset = self.k_target, self.offset_target
            self.shape_k = self.shape_k_target
            self.blending = False

    def _material(self, sim):
        """Set k, d, the axial inertia, air, friction and the sag-free offsets (self.offset)."""
        p = sim.params
        k = p.bending_stiffness / sim.length
        k[:, 0] *= p.root_stiffness_scale
        self.k = np.ascontiguousarray(k)
        self.d = np.ascontiguousarray(JOINT_DAMPING_SHARE * p.damping * inertia_beyond(
            self.modeled, sim.length, sim.mass))
        self.inertia_axial = np.ascontiguousarray(0.5 * sim.mass * p.bundle_radius ** 2)
        self.air = self.air_damping_rate(p)
        self.friction = p.contact_friction
        self.shape_k = np.ascontiguousarray(p.shape_stiffness * sim.length)
        self.shape_dir = np.ascontiguousarray(self.modeled[..., :, 2])
        self.sag_by_height = SAG_BY_HEIGHT
        if p.gravity_compensation:
            gravity = [0.0, 0.0, -p.gravity]
            with np.errstate(over='ignore', invalid='ignore'):
                offset = sag_free_offsets(self.modeled, sim.length, sim.mass, self.k, gravity)
                offset[..., 2] = 0.0    # a 2-DOF joint's constraint holds the twist torque
                # a joint whose spring would need more than MAX_PRELOAD of deflection to
                # hold the style is stiffened until MAX_PRELOAD holds it (e0 = R^T tau / k)
                size = np.linalg.norm(offset, axis=-1)
                factor = np.maximum(size / MAX_PRELOAD, 1.0)
                k = self.k * factor
                offset /= factor[..., None]
            # a follicle so soft that its deflection's size overflows (root_stiffness_scale
            # 1e-300: every step then diverged): the same stiffening, from the torque
            # itself, R^T tau (the offsets at k = 1)
            soft = ~np.isfinite(size)
            if soft.any():
                torque = sag_free_offsets(self.modeled, sim.length, sim.mass,
                                          np.ones_like(self.k), gravity)[soft]
                torque[:, 2] = 0.0
                k[soft] = np.linalg.norm(torque, axis=-1) / MAX_PRELOAD
                offset[soft] = torque / k[soft][:, None]
            # a strand whose style is an unstable equilibrium gets stiffer joints, all of
            # them by the same factor (the offsets shrink by it: the same torques hold the
            # same pose), until its stiffness beats gravity's by STABILITY_MARGIN
            need = stiffness_to_hold(self.modeled, sim.length, sim.mass, k,
                                     [0.0, 0.0, -p.gravity])
            scale = np.maximum(STABILITY_MARGIN * need, 1.0)
            self.k = np.ascontiguousarray(k * scale[:, None])
            offset /= scale[:, None, None]
            self.stabilized = float((scale > 1.0).mean())
            self.stiffened = float(((factor > 1.0) | (scale[:, None] > 1.0)).mean())
        else:
            offset = np.zeros(self.modeled.shape[:2] + (3,))
            self.stiffened = self.stabilized = 0.0
        self.offset = np.ascontiguousarray(offset)

    def state(self):
        """Return the kernel's view of the arrays, shared and not copied."""
        return ChainState(R=self.R, omega=self.omega, alpha=self.alpha, rest_rel=self.rest_rel,
                          k=self.k, d=self.d, inertia_axial=self.inertia_axial,
                          offset=self.offset, air=self.air, friction=self.friction,
                          sag_by_height=self.sag_by_height, shape_k=self.shape_k,
                          shape_dir=self.shape_dir)

    @staticmethod
    def contact_hinge(head, h, h_prev, params):
        """Return None: the joint springs act in the chain, with the contacts (implicit)."""
        return None

    def place(self, sim, world_dir):
        """Put every segment along world_dir (n_strands, n_segments, 3), at rest."""
        self.placed = True
        self._end_blend()
        # from the modeled root frame under the head, so the root joint is not twisted (a
        # turn from the head's own axes would be ill-defined for a strand hanging down)
        first = sim.head_pose[0] @ self.modeled[:, 0]
        self.R[:] = frames_along(world_dir, first)
        twist_free_chains(self.R, self.rest_rel, np.ascontiguousarray(sim.head_pose[0]))
        self.hold()

    def place_at_rest(self, sim):
        """Put every segment at its modeled orientation under the current head."""
        self.placed = True
        self._end_blend()
        self.R[:] = sim.head_pose[0] @ self.modeled
        self.hold()

    def hold(self):
        """Forget the motion: every segment at rest (zero angular velocity)."""
        self.omega[:] = 0.0
        self.alpha[:] = 0.0

    def rotate(self, dR):
        """Turn every segment rigidly by dR (a teleport of the head)."""
        self.R[:] = dR @ self.R
        self.hold()

    def step_state(self):
        """Return the arrays a step changes (the simulator copies them for its retry)."""
        return self.R, self.omega, self.alpha

    def velocities(self, sim, h_prev):
        """sim.vel is exact already (the last step wrote it)."""

    def substeps_for(self, h):
        """
        Return how many substeps of a step of h each strand needs (n_strands,).

        A (sub)step turns no segment by more than MAX_STEP_ROTATION, so a whipping tip
        (tens of rad/s) costs a few substeps instead of stability. The simulator decides
        whether the strands share the largest count or each takes its own.
        """
        strand_swings(self.R, self.omega, self._swings)
        need = np.ceil(h * self._swings / MAX_STEP_ROTATION)
        # (a diverged strand, NaN, takes 1: the simulator's check reports it)
        return np.where(np.isfinite(need), np.clip(need, 1.0, MAX_SUBSTEPS),
                        1.0).astype(np.int64)

    def outran(self, h, counts):
        """
        Return which strands outran the substeps they took in a step of h (n_strands,).

        A strand outran them when its swing at the end of the step needs more than
        OUTRAN_FACTOR times as many (each count is set from the swing where the step
        starts); a NaN strand has outrun them too.
        """
        return self._swing_past(h, counts, OUTRAN_FACTOR)

    def sped_up(self, h, counts):
        """
        Return which strands end a step of h needing more substeps than counts (n_strands,).

        Their swing at the step's end, unclipped (MAX_SUBSTEPS), over MAX_STEP_ROTATION a
        substep; NaN counts as sped up.
        """
        return self._swing_past(h, counts, 1.0)

    def _swing_past(self, h, counts, factor):
        """Return where the swing at a step's end needs over factor times counts substeps."""
        strand_swings(self.R, self.omega, self._swings)
        return ~(h * self._swings <= factor * MAX_STEP_ROTATION * counts)

    def gained_energy(self, sim, strands_before, before, which):
        """
        Return which of the strands `which` ended a step with more energy than it began.

        strands_before is (pos, vel) where the step began, before the model's own state
        there (as step_state lists it); more means more than ENERGY_SLACK times the
        strand's weight times its length. The caller picks strands nothing could give
        energy to (the simulator's _gained_energy), so that a rise is the step's own.
        """
        pos0, vel0 = strands_before
        R0, omega0 = before[:2]
        material = (sim.mass, sim.length, self.inertia_axial, self.rest_rel, self.k,
                    self.offset, self.shape_dir, self.shape_k)
        R_head = np.ascontiguousarray(sim.head_pose[0])
        start = np.zeros(len(which))
        end = np.zeros(len(which))
        for chain, out in (((R0, omega0, pos0, vel0), start),
                           ((self.R, self.omega, sim.pos, sim.vel), end)):
            self._energies_call(sim.layout_version,
                                chain,
                                material,
                                R_head,
                                sim.params.gravity,
                                which,
                                out)
        slack = ENERGY_SLACK * sim.params.gravity * (sim.mass.sum(1) * sim.length.sum(1))
        return which & (end > start + slack)

    def step(self, sim, strand_h, head, strand_t):
        """
        Advance each chain by its strand_h (0: it waits) with the forces in sim.forces.

        strand_t is when each strand's step ends. Returns the segments updated.
        """
        return step_chains(
            self.state(),
            sim.strands,
            sim.forces,
            head,
            sim.roots,
            sim.root_vel,
            sim.root_acc,
            sim.bodies,
            sim.params.collisions,
            (strand_h, strand_t),
            sim.stats,
            self.scratch,
        )

    def simulate(self, sim, step, counts, head, bodies, settings):
        """
        Take a whole step of substeps (forces and chains) in one kernel call; see chain_step.

        step is (t at its end, h, n substeps, forces at mid-step), counts each strand's
        (at most n).
        """
        return self._step_call(
            sim.layout_version,
            self.state(),
            sim.strands,
            sim._pos_mid,
            sim.forces,
            bodies,
            head,
            sim.attachment,
            sim.wind.field,
            (sim._strip_springs, sim._spring_constants),
            settings,
            step,
            counts,
            self._strand_h,
            self._strand_t,
            sim.stats,
            self.scratch,
        )

    def kinetic_energy(self, sim):
        """Return the exact kinetic energy (J): translation of the centres and rotation."""
        v = 0.5 * (sim.vel[:, 1:] + sim.vel[:, :-1])   # centre velocity of a rigid rod
        d = self.R[..., :, 2]
        w = self.omega
        wd = (w * d).sum(-1)
        w_perp2 = (w * w).sum(-1) - wd ** 2
        ip = sim.mass * sim.length ** 2 / 12.0
        return float(0.5 * (sim.mass * (v * v).sum(-1)).sum()
                     + 0.5 * (ip * w_perp2 + self.inertia_axial * wd ** 2).sum())

    def potential_energy(self, sim):
        """Return the springs' energy (J): sum of k bend_energy over the joints."""
        q = np.zeros((3, 3))
        total = 0.0
        R_head = sim.head_pose[0]
        for s in range(self.R.shape[0]):
            for i in range(self.R.shape[1]):
                parent = R_head if i == 0 else self.R[s, i - 1]
                joint_rotation(parent, self.rest_rel[s, i], self.R[s, i], q)
                total += self.k[s, i] * bend_energy(q, self.offset[s, i])
        # the shape springs: kg ang^2 / 2, ang between a rod and its modeled direction
        modeled = self.shape_dir @ R_head.T
        cos_ang = np.clip((modeled * self.R[..., :, 2]).sum(-1), -1.0, 1.0)
        total += float((0.5 * self.shape_k * np.arccos(cos_ang) ** 2).sum())
        return total

    @staticmethod
    def air_damping_rate(params):
        """Return the drag rate (1/s) against still air: air_damping and its share of damping."""
        return float(params.air_damping + AIR_DAMPING_SHARE * params.damping)

    @staticmethod
    def stability_problem(params, length, dt, margin):
        """
        Return why params would be unstable at dt for these segment lengths, or None.

        The joint springs, contacts and air drag are implicit (the drag half, which makes
        it trapezoidal); what stays explicit is gravity's tension (the weight of everything
        beyond a joint, acting with the segment's lever) and the inter-strip springs at the
        segment's end. Each acts against the segment's inertia plus the implicit spring and
        damper's share.
        """
        mass = params.linear_density * length
        k = params.bending_stiffness / length
        k[..., 0] *= params.root_stiffness_scale
        d = JOINT_DAMPING_SHARE * params.damping * mass * length ** 2 / 3.0  # least beyond
        inertia = mass * length ** 2 / 3.0 + GAMMA * dt * dt * k + dt * d
        beyond = np.cumsum(mass[..., ::-1], axis=-1)[..., ::-1]
        springs = 0.0
        if params.inter_strip:
            springs += params.neighbor_stiffness + params.wall_stiffness + \
                params.scalp_stiffness
        # (contacts are taken implicitly; so is half the air drag, which makes it
        # trapezoidal and stable at any rate)
        explicit = (beyond * params.gravity * length + springs * length ** 3) / inertia
        return explicit_stability_problem(explicit, 0.0, dt, margin,
                                          'the articulated model (gravity tension, springs)')
