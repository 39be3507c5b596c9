"""
Visibility culling: strips that cannot be seen from a viewpoint are not drawn (thesis 3.3).

A strip is skipped only when all of it, its face, its U-shape walls and the refinement
between its simulated vertices, lies in the shadow of the head's spheres (so it faces away
too). The shadow used is a convex part of the true one: the rays from the eye that touch
sphere S form a cone; every point of that cone beyond the plane of the circle where the
cone touches S has passed through S (the near cap of S lies in front of that plane). A
cone (half-angle < 90 deg) cut by a half-space is convex, so a set whose corners lie in it
lies in it whole: a bilinear patch is hidden when its four corners, each grown into a
ball, are in the shadow of one sphere. No trigonometry: each sphere's cone is kept as its
axis and the sine and cosine of its half-angle.

A strip with a simulated vertex in plain view is visible at once (most visible strips
stop there, after a few dot products). The others are proven hidden piece by piece, the
walls' projections worked out only where needed. Every wall runs from an edge point
towards the projection sphere S (or is a short fix-up), and a sphere with the convex part
of its shadow is convex too, so a sphere that holds S holds the walls of any vertices its
shadow holds grown by the fix-up length: the whole strip at once, or two rows at a time,
without projecting. Rows that no such sphere holds get their wall bottoms (the
projections of the simulated vertices) and are held by one shadow with them, or else
their three patches (the face between the two edges, and each edge with its wall) are,
each split at most MAX_SPLITS times. Anything left over is drawn. The spheres are tried
from the one that held the last piece. The test suite checks against a ray caster that no
culled strip is hit by any ray.
"""

from math import sqrt

from numba import njit
import numpy as np

from hair_sim.kernels import njit_without_refcounts
from hair_sim.render.ushape import strip_wall_bottoms

MARGIN = 1e-4             # m: every corner ball grows by this much
MAX_SPLITS = 3            # a patch no one shadow holds is split in four, this deep at most
SPLIT_ROWS = 3 * MAX_SPLITS + 2      # the most pieces waiting at once, and a scratch row


@njit(cache=True)
def shadow_cones(eye, occ):
    """
    Return per occluding sphere (axis x, y, z, sin, cos of the half-angle, plane depth).

    The plane depth is the distance along the axis from the eye to the circle where the
    cone touches the sphere: t cos(alpha) = t^2 / |ES|, t the tangent length. A sphere
    around the eye (or of no size) hides nothing: its sine is set to -1.
    """
    n = occ.shape[0]
    out = np.zeros((n, 6))
    for k in range(n):
        cx, cy, cz = occ[k, 0] - eye[0], occ[k, 1] - eye[1], occ[k, 2] - eye[2]
        dc = sqrt(cx * cx + cy * cy + cz * cz)
        r = occ[k, 3]
        if dc <= r or r <= 0.0:
            out[k, 3] = -1.0
            continue
        t = sqrt(dc * dc - r * r)
        out[k, 0], out[k, 1], out[k, 2] = cx / dc, cy / dc, cz / dc
        out[k, 3], out[k, 4], out[k, 5] = r / dc, t / dc, t * t / dc
    return out


@njit_without_refcounts
def ball_in_shadow(x, y, z, rho, eye, cones, k):
    """Return True if the ball (x, y, z; rho) lies in the shadow of sphere k (convex part)."""
    sa = cones[k, 3]
    if sa < 0.0:
        return False
    dx, dy, dz = x - eye[0], y - eye[1], z - eye[2]
    along = dx * cones[k, 0] + dy * cones[k, 1] + dz * cones[k, 2]
    if along - rho < cones[k, 5]:                  # not wholly beyond the tangent circle
        return False
    db = sqrt(dx * dx + dy * dy + dz * dz)
    sb = rho / db                                  # sine of the ball's angular radius
    if sb > sa:
        return False
    # the ball's direction within alpha - beta of the axis: cos(gamma) >= cos(alpha - beta)
    return along >= db * (cones[k, 4] * sqrt(1.0 - sb * sb) + sa * sb)


@njit_without_refcounts
def _nth_sphere(first, i, n):
    """Return the i-th of n spheres counted on from `first` (wrapping round)."""
    k = first + i
    return k - n if k >= n else k


@njit_without_refcounts
def _held(work, row, rho, eye, cones, first):
    """Return the sphere whose shadow holds the 4 corners work[row, :12], or -1."""
    n = cones.shape[0]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        held = True
        for c in range(4):
            if not ball_in_shadow(work[row, 3 * c], work[row, 3 * c + 1],
                                  work[row, 3 * c + 2], rho, eye, cones, k):
                held = False
                break
        if held:
            return k
    return -1


@njit_without_refcounts
def quad_in_shadow(work, rho, eye, cones, first):
    """
    Return a sphere that held the bilinear patch of corners work[0, :12], grown by rho.

    The corners are p00, p01, p10, p11 (x, y, z each). The patch is hidden when one
    sphere's shadow holds the four corners (the patch lies in their hull); otherwise it is
    split in four (a piece of a bilinear patch is the bilinear patch of its corners), at
    most MAX_SPLITS deep. Returns -1 if some piece is not held. Spheres are tried from
    `first` on, then from the one that held the last piece. work (SPLIT_ROWS, 13) is the
    stack of pieces (corners and depth), its last row scratch.
    """
    k = _held(work, 0, rho, eye, cones, first)
    if k >= 0 or MAX_SPLITS == 0:
        return k
    k = first
    last = SPLIT_ROWS - 1                        # the parent piece's row
    work[0, 12] = 0.0
    top = 1
    while top > 0:
        top -= 1
        for i in range(13):                      # copied: pieces are pushed into its row
            work[last, i] = work[top, i]
        for half in range(4):                    # the four (t, f) halves of the patch
            for c in range(4):
                t = 0.5 * ((half // 2) + (1 if c >= 2 else 0))
                f = 0.5 * ((half % 2) + (c % 2))
                for d in range(3):
                    work[top, 3 * c + d] = \
                        (1 - t) * ((1 - f) * work[last, d] + f * work[last, 3 + d]) + \
                        t * ((1 - f) * work[last, 6 + d] + f * work[last, 9 + d])
            held = _held(work, top, rho, eye, cones, k)
            if held >= 0:
                k = held
                continue
            if work[last, 12] + 1.0 >= MAX_SPLITS:
                return -1
            work[top, 12] = work[last, 12] + 1.0
            top += 1
    return k


@njit_without_refcounts
def _set_quad(work, P, s0, Q, s1, j):
    """work[0, :12] = P[s0, j], Q[s1, j], P[s0, j + 1], Q[s1, j + 1] (no array views)."""
    for d in range(3):
        work[0, d] = P[s0, j, d]
        work[0, 3 + d] = Q[s1, j, d]
        work[0, 6 + d] = P[s0, j + 1, d]
        work[0, 9 + d] = Q[s1, j + 1, d]


@njit_without_refcounts
def _rows_held(pos, strands, bottoms, j0, j1, grow, eye, cones, first):
    """Return the sphere whose shadow holds rows j0..j1 (edges, wall bottoms), or -1."""
    a, b = strands
    n = cones.shape[0]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        held = True
        for q in range(2):
            st = a if q == 0 else b
            for j in range(j0, j1 + 1):
                g = grow[q, j]
                if not (ball_in_shadow(pos[st, j, 0], pos[st, j, 1], pos[st, j, 2], g, eye,
                                       cones, k)
                        and ball_in_shadow(bottoms[st, j, 0], bottoms[st, j, 1],
                                           bottoms[st, j, 2], g, eye, cones, k)):
                    held = False
                    break
            if not held:
                break
        if held:
            return k
    return -1


@njit(cache=True)
def holds_projection_sphere(projection, eye, cones, occ):
    """Return per sphere whether it, or the convex part of its shadow, holds the sphere S."""
    c, rs = projection.centre, projection.rs
    out = np.zeros(occ.shape[0], dtype=np.bool_)
    for k in range(occ.shape[0]):
        dx, dy, dz = c[0] - occ[k, 0], c[1] - occ[k, 1], c[2] - occ[k, 2]
        out[k] = (sqrt(dx * dx + dy * dy + dz * dz) + rs <= occ[k, 3]
                  or ball_in_shadow(c[0], c[1], c[2], rs, eye, cones, k))
    return out


@njit_without_refcounts
def _held_with_any_walls(pos, strands, rows, grow, projection, shadows, first):
    """
    Return a sphere whose shadow holds rows j0..j1 and every wall they could have, or -1.

    No wall bottom is worked out: a wall runs from an edge point A to its projection,
    which lies on the segment from A to A', a point of the projection sphere S (the
    bisection of thesis 3.2), or is A moved by the fix-up length C. Sphere k with the
    convex part of its shadow is itself convex (the cone touches the sphere along the
    circle that bounds the part): when S lies in sphere k (or in its shadow) and every
    simulated vertex of the rows, grown by its deviation and C, lies in the shadow, so do
    those rows with their walls, whatever the projections turn out to be.
    shadows is (eye, cones, which spheres hold S: holds_projection_sphere).
    """
    a, b = strands
    j0, j1 = rows
    eye, cones, holds_s = shadows
    fix = projection.fix_len
    n = cones.shape[0]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        if not holds_s[k]:
            continue
        held = True
        for q in range(2):
            st = a if q == 0 else b
            for j in range(j0, j1 + 1):
                if not ball_in_shadow(pos[st, j, 0], pos[st, j, 1], pos[st, j, 2],
                                      grow[q, j] + fix, eye, cones, k):
                    held = False
                    break
            if not held:
                break
        if held:
            return k
    return -1


@njit_without_refcounts
def _strip_hidden(pos, strip, walls, grow, shadows, first, work):
    """
    Return a sphere that held the last piece of a hidden strip, or -1 if it may be seen.

    strip is (s, strip_strands, sigma_s); walls (projection, bottoms, which rows have
    their bottoms worked out, the projection's scratch). Each pair of rows is held by one
    sphere's shadow without projecting its walls (_held_with_any_walls), or else its wall
    bottoms are worked out and one shadow holds the rows and bottoms, or else each of
    its three patches (the face between the edges, each edge with its wall), split as
    quad_in_shadow does. Corner balls grow by grow (2, V).
    """
    s, strip_strands, sigma_s = strip
    projection, bottoms, projected, spans = walls
    eye, cones, _ = shadows
    a, b = strip_strands[s, 0], strip_strands[s, 1]
    strands = (a, b)
    V = pos.shape[1]
    k = first
    for j in range(V - 1):
        held = _held_with_any_walls(pos, strands, (j, j + 1), grow, projection, shadows, k)
        if held >= 0:
            k = held
            continue
        for r in range(j, j + 2):
            if not projected[r]:
                strip_wall_bottoms(pos, strip_strands, s, sigma_s, projection, (r, r),
                                   bottoms, spans)
                projected[r] = True
        held = _rows_held(pos, strands, bottoms, j, j + 1, grow, eye, cones, k)
        if held >= 0:
            k = held
            continue
        rho = max(grow[0, j], grow[0, j + 1], grow[1, j], grow[1, j + 1])
        _set_quad(work, pos, a, pos, b, j)       # the face between the edges
        k = quad_in_shadow(work, rho, eye, cones, k)
        if k < 0:
            return -1
        for q in range(2):                       # each edge with its wall
            st = a if q == 0 else b
            _set_quad(work, pos, st, bottoms, st, j)
            k = quad_in_shadow(work, max(grow[q, j], grow[q, j + 1]), eye, cones, k)
            if k < 0:
                return -1
    return k


@njit(cache=True)
def visible_strips(pos,
                   strip_strands,
                   sigma,
                   projection,
                   eye,
                   occ,
                   bottoms,
                   out):
    """
    Write the strips that may be seen from eye into out[:count], in order; return count.

    The drawn edge of a strip is an Oslo refinement of its simulated edge polygon and lies
    within |second difference| / 6 of it (refined control polygons of a cubic B-spline
    stay between the control polygon and the curve); its wall runs down to bottoms close
    to those of the simulated vertices. Every corner ball is grown by the largest such
    deviation around it and MARGIN. The wall bottoms (scratch array `bottoms`) are worked
    out only for strips without a simulated vertex in plain view.
    """
    cones = shadow_cones(eye, occ)
    n_strips = strip_strands.shape[0]
    V = pos.shape[1]
    grow = np.empty((2, V))
    last = 0                                     # the sphere that held the last piece
    n_occ = cones.shape[0]
    spans = np.empty((projection.scalp.shape[0], 2))  # the wall bottoms' scratch
    work = np.empty((SPLIT_ROWS, 13))           # quad_in_shadow's pieces
    projected = np.zeros(V, dtype=np.bool_)      # rows whose wall bottoms are worked out
    shadows = (eye, cones, holds_projection_sphere(projection, eye, cones, occ))
    count = 0
    for s in range(n_strips):
        a, b = strip_strands[s, 0], strip_strands[s, 1]
        vis = False
        for q in range(2):                       # cheap and exact first
            st = a if q == 0 else b
            for j in range(V):
                hidden = False
                for i in range(n_occ):           # from the sphere that held the last
                    k = _nth_sphere(last, i, n_occ)
                    if ball_in_shadow(pos[st, j, 0], pos[st, j, 1], pos[st, j, 2], 0.0, eye,
                                      cones, k):
                        hidden = True
                        last = k
                        break
                if not hidden:
                    vis = True
                    break
            if vis:
                break
        if not vis:
            for q in range(2):                   # the largest deviation around each vertex
                st = a if q == 0 else b
                for j in range(V):
                    grow[q, j] = MARGIN
                for j in range(1, V - 1):        # |P[j-1] - 2 P[j] + P[j+1]| / 6
                    dx = pos[st, j - 1, 0] - 2 * pos[st, j, 0] + pos[st, j + 1, 0]
                    dy = pos[st, j - 1, 1] - 2 * pos[st, j, 1] + pos[st, j + 1, 1]
                    dz = pos[st, j - 1, 2] - 2 * pos[st, j, 2] + pos[st, j + 1, 2]
                    g = sqrt(dx * dx + dy * dy + dz * dz) / 6.0 + MARGIN
                    for r in range(j - 1, j + 2):
                        if g > grow[q, r]:
                            grow[q, r] = g
            k = _held_with_any_walls(pos, (a, b), (0, V - 1), grow, projection, shadows, last)
            if k >= 0:                           # hidden, walls and all: nothing projected
                last = k
                continue
            projected[:] = False
            k = _strip_hidden(pos,
                              (s, strip_strands, sigma[s]),
                              (projection, bottoms, projected, spans),
                              grow,
                              shadows,
                              last,
                              work)
            vis = k < 0
            if not vis:
                last = k
        if vis:
            out[count] = s
            count += 1
    return count
