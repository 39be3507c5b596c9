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
stop there, after a few dot products). For the others, the spheres whose shadow can
reach the ball around the strip's vertices are its candidates, and a table holds how deep
each vertex lies in each candidate's shadow (shadow_depths: a ball around a point is in a
shadow when its radius is at most that depth; one vectorised loop, no branch). The strip
is then proven hidden piece by piece, the walls worked out only where needed, cheapest
bound first. Every wall runs from an edge point towards the projection sphere S (or is a
short fix-up), and a sphere with the convex part of its shadow is convex too, so a sphere
that holds S holds the walls of any vertices its shadow holds grown by the fix-up length:
the whole strip at once, or two rows at a time. Below the head (the neck's and body's
spheres do not hold S), a wall lies within max_dist of its edge point, or within the
fix-up length where no scalp sphere is near (wall_extents), or in the hull of the fix-up
ball and the segment to where it can reach (ushape.strip_wall_reach); only rows held by
none of these get their wall bottoms worked out (the projection of thesis 3.2). Rows are
held piece by piece (the face between the two edges, and each edge with its wall), each
piece by one shadow, or else split at most MAX_SPLITS times. Anything left over is drawn.
The spheres are tried from the one that held the last piece. A strip whose proof failed
(every simulated vertex in shadow, yet some part may be seen: it lies on the silhouette)
is drawn without a proof for the next PROOF_REST calls: drawing a strip is always safe, and
a failed proof costs more than drawing it. A strip proven hidden keeps the proof's
certificate (per row, by which bound it was held and which spheres held it); the next call
checks that first (certificate_holds), a proof of the strands as they are then, without
the search. The test suite checks
against a ray caster that no culled strip is hit by any ray, on every shipped style, and
that the wall bounds hold the walls the projection gives.
"""

from math import sqrt

from numba import njit
import numpy as np

from hair_sim.kernels import inlined_without_refcounts, njit_without_refcounts
from hair_sim.render.ushape import strip_wall_bottoms, strip_wall_reach

MARGIN = 1e-4             # m: every corner ball grows by this much
MAX_SPLITS = 3            # a patch no one shadow holds is split in four, this deep at most
SPLIT_ROWS = 3 * MAX_SPLITS + 2      # the most pieces waiting at once, and a scratch row
# calls for which a strip whose proof failed is drawn without one. Measured on thesis_long
# from the front: its two silhouette strips cost 1.5 us each to fail, against 1.3 us to draw
PROOF_REST = 8
# A strip proven hidden keeps its proof's certificate, per row pair the level that held
# it and the spheres: one sphere for the row and every wall it could have (by the fix-up
# length, a sphere that holds S; or by wall_extents), or one for the face and one for each
# edge with its wall (by how far the walls reach, or by their bottoms worked out); or
# that it was held piece by piece after splits. The next call checks that first
# (certificate_holds): the proof again, without the search that found it (for a split
# row, the cheaper levels' search).
PROOF_FIX_UP = 1
PROOF_EXTENTS = 2
PROOF_REACH = 3
PROOF_BOTTOMS = 4
PROOF_SPLITS = 5         # (its sphere only where the search starts: the pieces are searched)


@njit_without_refcounts
def _proof_code(level, face, edge_a, edge_b):
    """Return a row's certificate: its level and spheres (< 256 each) in one int64."""
    return level | (face << 3) | (edge_a << 11) | (edge_b << 19)


@njit_without_refcounts
def _proof_spheres(code):
    """Return the (face, edge a, edge b) spheres of a row's certificate."""
    return (code >> 3) & 255, (code >> 11) & 255, (code >> 19) & 255


@njit(cache=True)
def shadow_cones(eye, occ):
    """Return shadow_cones_into's table (n_occ, 6) of the occluding spheres occ."""
    out = np.zeros((occ.shape[0], 6))
    shadow_cones_into(eye, occ, out)
    return out


@njit_without_refcounts
def shadow_cones_into(eye, occ, out):
    """
    Write per occluding sphere (axis x, y, z, sin, cos of the half-angle, plane depth).

    The plane depth is the distance along the axis from the eye to the circle where the
    cone touches the sphere: t cos(alpha) = t^2 / |ES|, t the tangent length. A sphere
    around the eye (or of no size) hides nothing: its sine is set to -1.
    """
    for k in range(occ.shape[0]):
        for d in range(6):
            out[k, d] = 0.0
        cx, cy, cz = occ[k, 0] - eye[0], occ[k, 1] - eye[1], occ[k, 2] - eye[2]
        dc = sqrt(cx * cx + cy * cy + cz * cz)
        r = occ[k, 3]
        if dc <= r or r <= 0.0:
            out[k, 3] = -1.0
            continue
        t = sqrt(dc * dc - r * r)
        out[k, 0], out[k, 1], out[k, 2] = cx / dc, cy / dc, cz / dc
        out[k, 3], out[k, 4], out[k, 5] = r / dc, t / dc, t * t / dc


@njit_without_refcounts
def ball_in_shadow(x, y, z, rho, eye, cones, k):
    """
    Return True if the ball (x, y, z; rho) lies in the shadow of sphere k (convex part).

    The ball is inside when its centre is at least rho from both of the part's boundaries:
    the plane of the tangent circle (along - depth >= rho) and the cone. A point at angle
    gamma < alpha from the axis, at distance db from the eye, is db sin(alpha - gamma)
    from the cone, that is sin(alpha) along - cos(alpha) perp, with along and perp its
    coordinates along and off the axis: one square root, no division.
    """
    sa = cones[k, 3]
    if sa < 0.0:
        return False
    dx, dy, dz = x - eye[0], y - eye[1], z - eye[2]
    along = dx * cones[k, 0] + dy * cones[k, 1] + dz * cones[k, 2]
    if along - rho < cones[k, 5]:                  # not wholly beyond the tangent circle
        return False
    px = dx - along * cones[k, 0]
    py = dy - along * cones[k, 1]
    pz = dz - along * cones[k, 2]
    return sa * along - cones[k, 4] * sqrt(px * px + py * py + pz * pz) >= rho


@njit_without_refcounts
def shadow_depth(x, y, z, eye, cones, k):
    """
    Return how deep the point (x, y, z) lies in the shadow of sphere k (negative: outside).

    A ball of radius rho around it lies in the shadow when this is >= rho (ball_in_shadow
    decides the same, with early exits). It is the smaller of two functions that change
    by at most the distance moved (the depth beyond the tangent circle's plane, and
    sin(alpha) along - cos(alpha) perp), so a point within r of (x, y, z) is at most r
    less deep. -inf for a sphere that hides nothing.
    """
    if cones[k, 3] < 0.0:
        return -np.inf
    dx, dy, dz = x - eye[0], y - eye[1], z - eye[2]
    along = dx * cones[k, 0] + dy * cones[k, 1] + dz * cones[k, 2]
    px = dx - along * cones[k, 0]
    py = dy - along * cones[k, 1]
    pz = dz - along * cones[k, 2]
    return min(along - cones[k, 5],
               cones[k, 3] * along - cones[k, 4] * sqrt(px * px + py * py + pz * pz))


@njit_without_refcounts
def shadow_depths(points, n, eye, cones, out):
    """
    Write out[k, i]: how deep point i lies in the shadow of sphere k (negative: outside).

    points is (3, >= n), x, y and z of a point in a column; a ball of radius rho around
    point i lies in shadow k when out[k, i] >= rho (the measure of ball_in_shadow: the
    distance to the nearer of the part's plane and cone, for a point inside). Written
    without a branch so that the loop over the points is vectorised; a sphere that hides
    nothing gets -inf.
    """
    for k in range(cones.shape[0]):
        ux, uy, uz = cones[k, 0], cones[k, 1], cones[k, 2]
        sa, ca, plane = cones[k, 3], cones[k, 4], cones[k, 5]
        hides = sa >= 0.0
        for i in range(n):
            dx, dy, dz = points[0, i] - eye[0], points[1, i] - eye[1], points[2, i] - eye[2]
            along = dx * ux + dy * uy + dz * uz
            px, py, pz = dx - along * ux, dy - along * uy, dz - along * uz
            cone = sa * along - ca * sqrt(px * px + py * py + pz * pz)
            d = min(cone, along - plane)
            out[k, i] = d if hides else -np.inf


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
def _face_held(depth, rows, grow, first):
    """Return a sphere whose shadow holds the face between the edges of rows j, j + 1."""
    j, _ = rows
    n = depth.shape[0]
    V = grow.shape[1]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        if depth[k, j] >= grow[0, j] and depth[k, j + 1] >= grow[0, j + 1] and \
                depth[k, V + j] >= grow[1, j] and depth[k, V + j + 1] >= grow[1, j + 1]:
            return k
    return -1


@njit_without_refcounts
def _wall_held(depth, edge, rows, grow, shadows, first):
    """
    Return a sphere whose shadow holds strand q's wall below rows j, j + 1, or -1.

    edge is (q, its strand, ends): the wall bottoms, or how far the walls reach; rows is
    (j, extra): the edge points' balls grow by grow + extra (their depths in the shadows
    are the table depth, point q V + j), the ends' by grow.
    """
    q, st, ends = edge
    j, extra = rows
    eye, cones = shadows
    n = depth.shape[0]
    V = grow.shape[1]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        if depth[k, q * V + j] >= grow[q, j] + extra and \
                depth[k, q * V + j + 1] >= grow[q, j + 1] + extra and \
                ball_in_shadow(ends[st, j, 0], ends[st, j, 1], ends[st, j, 2], grow[q, j],
                               eye, cones, k) and \
                ball_in_shadow(ends[st, j + 1, 0], ends[st, j + 1, 1], ends[st, j + 1, 2],
                               grow[q, j + 1], eye, cones, k):
            return k
    return -1


@njit_without_refcounts
def _pieces_held(depth, strip, rows, grow, shadows, first):
    """
    Return (face, edge a, edge b): the spheres that held the three pieces of rows j, j + 1.

    The pieces are the face between the edges and each edge with its wall (its corners
    grown as _wall_held says), each held by one sphere, not necessarily the same; edge b's
    is -1 if some piece is not held. strip is (strands a, b, ends); rows (j, extra);
    shadows (eye, cones).
    """
    a, b, ends = strip
    face = _face_held(depth, rows, grow, first)
    if face < 0:
        return -1, -1, -1
    edge_a = _wall_held(depth, (0, a, ends), rows, grow, shadows, face)
    if edge_a < 0:
        return face, -1, -1
    return face, edge_a, _wall_held(depth, (1, b, ends), rows, grow, shadows, edge_a)


@njit_without_refcounts
def holds_projection_sphere(projection, eye, cones, occ, out):
    """Write per sphere whether it, or the convex part of its shadow, holds the sphere S."""
    c, rs = projection.centre, projection.rs
    for k in range(occ.shape[0]):
        dx, dy, dz = c[0] - occ[k, 0], c[1] - occ[k, 1], c[2] - occ[k, 2]
        out[k] = (sqrt(dx * dx + dy * dy + dz * dz) + rs <= occ[k, 3]
                  or ball_in_shadow(c[0], c[1], c[2], rs, eye, cones, k))


@njit_without_refcounts
def _held_with_any_walls(depth, rows, grow, walls, holds_s, first):
    """
    Return a sphere whose shadow holds rows j0..j1 and every wall they could have, or -1.

    No wall bottom is worked out. Each vertex's ball grows by its deviation and
    walls[q, j], a radius that holds its wall whatever the projection turns out to be:
    - the fix-up length C, with holds_s saying which spheres hold the projection sphere S
      (holds_projection_sphere), only those being tried. A wall runs from an edge point A
      to its projection, on the segment from A to A', a point of S (the bisection of
      thesis 3.2), or is A moved by C. Sphere k with the convex part of its shadow is
      itself convex (the cone touches the sphere along the circle that bounds the part):
      when S lies in it and the balls lie in the shadow, so do the walls.
    - wall_extents, with holds_s None: every sphere is tried.
    depth is the table of shadow_depths (point q V + j of strand q).
    """
    j0, j1 = rows
    n = depth.shape[0]
    V = grow.shape[1]
    for i in range(n):
        k = _nth_sphere(first, i, n)
        if holds_s is not None and not holds_s[k]:
            continue
        held = True
        for q in range(2):
            for j in range(j0, j1 + 1):
                if depth[k, q * V + j] < grow[q, j] + walls[q, j]:
                    held = False
                    break
            if not held:
                break
        if held:
            return k
    return -1


@njit_without_refcounts
def wall_extents(pos, strands, grow, projection, out):
    """
    Write out[q, j]: a radius around strand q's vertex j that holds its U-shape wall.

    A wall's bottom is on the segment from its edge point A towards A' within max_dist
    of A, or it is the fix-up, fix_len from A (strip_wall_bottoms): max(max_dist, fix_len)
    holds it. Where no scalp sphere comes within max_dist + delta of the drawn edge
    points near the vertex (within grow), the bisection's point (within delta of where AA'
    enters the scalp) is farther than max_dist, so the wall is the fix-up: fix_len holds it
    (the rows below the head, shadowed by the neck and body, whose spheres do not hold
    the projection sphere). No square root.
    """
    scalp = projection.scalp
    fix = projection.fix_len
    longest = max(projection.max_dist, fix)
    for q in range(2):
        st = strands[q]
        for j in range(pos.shape[1]):
            near = False
            for k in range(scalp.shape[0]):
                dx = pos[st, j, 0] - scalp[k, 0]
                dy = pos[st, j, 1] - scalp[k, 1]
                dz = pos[st, j, 2] - scalp[k, 2]
                r = scalp[k, 3] + projection.max_dist + projection.delta + grow[q, j]
                near |= dx * dx + dy * dy + dz * dz <= r * r
            out[q, j] = longest if near else fix


@njit_without_refcounts
def _deviations(pos, strands, grow):
    """
    Write grow (2, V), how far the drawn edges stray; return its largest value.

    grow[q, j] is MARGIN and the largest deviation of the drawn edges around simulated
    vertex j of strand q of (a, b). The drawn edge is an Oslo refinement of the simulated
    edge polygon and lies within |P[j-1] - 2 P[j] + P[j+1]| / 6 of it (refined control
    polygons of a cubic B-spline stay between the control polygon and the curve).
    """
    V = pos.shape[1]
    largest = MARGIN
    for q in range(2):
        st = strands[q]
        for j in range(V):
            grow[q, j] = MARGIN
        for j in range(1, V - 1):
            dx = pos[st, j - 1, 0] - 2 * pos[st, j, 0] + pos[st, j + 1, 0]
            dy = pos[st, j - 1, 1] - 2 * pos[st, j, 1] + pos[st, j + 1, 1]
            dz = pos[st, j - 1, 2] - 2 * pos[st, j, 2] + pos[st, j + 1, 2]
            g = sqrt(dx * dx + dy * dy + dz * dz) / 6.0 + MARGIN
            largest = max(largest, g)
            for r in range(j - 1, j + 2):
                grow[q, r] = max(grow[q, r], g)
    return largest


@inlined_without_refcounts
def _work_out_walls(pos, strip, walls, j, reach_only):
    """
    Work out the walls of rows j, j + 1 where not done yet for this strip.

    With reach_only, how far they can reach (strip_wall_reach, into reach; worked[0]);
    else their bottoms (strip_wall_bottoms, into bottoms; worked[1]). strip and walls as
    _strip_hidden takes them.
    """
    s, strip_strands, sigma_s = strip
    projection, bottoms, reach, worked, spans = walls
    w = 0 if reach_only else 1
    for r in range(j, j + 2):
        if not worked[w, r]:
            if reach_only:
                strip_wall_reach(pos, strip_strands, s, projection, (r, r), reach)
            else:
                strip_wall_bottoms(pos, strip_strands, s, sigma_s, projection, (r, r),
                                   bottoms, spans)
            worked[w, r] = True


@njit_without_refcounts
def _vertex_held(pos, st, r, rho, shadows, k):
    """Return whether the ball of radius rho around vertex r of strand st is in shadow k."""
    eye, cones = shadows[0], shadows[1]
    return shadow_depth(pos[st, r, 0], pos[st, r, 1], pos[st, r, 2], eye, cones, k) >= rho


@njit_without_refcounts
def certificate_holds(pos, strip, proof, walls, shadows, grow, work):
    """
    Return the sphere that held a strip's last row under its certificate, or -1.

    proof (V - 1,) is the certificate of an earlier proof (_strip_hidden's, _proof_code):
    per row pair j, j + 1 a level and its spheres. Each row is held as that level holds it,
    with those spheres only: the vertices' balls, grown by their deviations (_deviations,
    worked out again) and the fix-up length (the sphere must hold the projection sphere S)
    or their wall_extents, lie in one shadow (as _held_with_any_walls); or the face in one
    and each edge with its wall, the walls' reach or bottoms worked out again, in one each
    (as _pieces_held); or, for a row that needed splits, its pieces are searched again
    (_row_held_in_pieces), skipping the cheaper levels. That is a proof by itself, of the
    strands as they are now; the search for the spheres is what it saves. strip is (s,
    strip_strands, sigma_s); walls and grow as _strip_hidden takes them; shadows (eye,
    cones, which spheres hold S); work quad_in_shadow's pieces.
    """
    s, strip_strands, sigma_s = strip
    projection, bottoms, reach, worked, spans = walls
    eye, cones, holds_s = shadows
    grow, fix_ups, extents = grow
    a, b = strip_strands[s, 0], strip_strands[s, 1]
    strands = (a, b)
    _deviations(pos, strands, grow)
    worked[:] = False
    extents[0, 0] = -1.0                         # not worked out yet
    k = -1
    checked = -1                                 # vertex j was checked with this code
    for j in range(pos.shape[1] - 1):
        code = proof[j]
        level = code & 7
        face, edge_a, edge_b = _proof_spheres(code)
        k = edge_b
        if level <= PROOF_EXTENTS:
            if level == PROOF_FIX_UP:
                if not holds_s[k]:
                    return -1
                walls_q = fix_ups
            else:
                if extents[0, 0] < 0.0:
                    wall_extents(pos, strands, grow, projection, extents)
                walls_q = extents
            for q in range(2):
                for r in range(j if code != checked else j + 1, j + 2):
                    if not _vertex_held(pos, strands[q], r, grow[q, r] + walls_q[q, r],
                                        shadows, k):
                        return -1
            checked = code
            continue
        checked = -1
        if level == PROOF_SPLITS:
            _work_out_walls(pos, strip, walls, j, False)
            k = _row_held_in_pieces(pos, (a, b, bottoms), j, grow, (eye, cones), face, work)
            if k < 0:
                return -1
            continue
        extra = projection.fix_len if level == PROOF_REACH else 0.0
        for r in range(j, j + 2):                # the face: the four corners' balls
            for q in range(2):
                if not _vertex_held(pos, strands[q], r, grow[q, r], shadows, face):
                    return -1
        _work_out_walls(pos, strip, walls, j, level == PROOF_REACH)   # the walls' ends
        ends = reach if level == PROOF_REACH else bottoms
        for q in range(2):                       # each edge with its wall
            st = strands[q]
            kq = edge_a if q == 0 else edge_b
            for r in range(j, j + 2):
                if not _vertex_held(pos, st, r, grow[q, r] + extra, shadows, kq) or \
                        not ball_in_shadow(ends[st, r, 0], ends[st, r, 1], ends[st, r, 2],
                                           grow[q, r], eye, cones, kq):
                    return -1
    return k


@njit_without_refcounts
def _strip_hidden(pos, strip, walls, grow, shadows, first, work, proof):
    """
    Return a sphere that held the last piece of a hidden strip, or -1 if it may be seen.

    proof (V - 1,) gets each row pair's certificate (_proof_code: its level and the
    candidates that held it).
    strip is (s, strip_strands, sigma_s); walls (projection, bottoms, reach, which rows
    have them worked out (2, V), the projection's scratch); grow (the deviations (2, V),
    scratch for wall_extents); shadows (eye, the candidates' cones, which of them hold
    S, the table of the simulated vertices' depths in their shadows). Each pair of rows,
    cheapest first, is held:
    - by one shadow without working out its walls (_held_with_any_walls), or
    - grown by its wall_extents, or
    - piece by piece with how far its walls can reach (strip_wall_reach), or
    - piece by piece with its wall bottoms worked out (strip_wall_bottoms), or
    - piece by piece, each split as quad_in_shadow does.
    """
    s, strip_strands, sigma_s = strip
    projection, bottoms, reach, worked, spans = walls
    eye, cones, holds_s, depth = shadows
    grow, fix_ups, extents = grow
    extents[0, 0] = -1.0                         # not worked out yet
    a, b = strip_strands[s, 0], strip_strands[s, 1]
    strands = (a, b)
    V = pos.shape[1]
    k = first
    for j in range(V - 1):
        held = _held_with_any_walls(depth, (j, j + 1), grow, fix_ups, holds_s, k)
        if held >= 0:
            k = held
            proof[j] = _proof_code(PROOF_FIX_UP, held, held, held)
            continue
        if extents[0, 0] < 0.0:
            wall_extents(pos, strands, grow, projection, extents)
        held = _held_with_any_walls(depth, (j, j + 1), grow, extents, None, k)
        if held >= 0:
            k = held
            proof[j] = _proof_code(PROOF_EXTENTS, held, held, held)
            continue
        _work_out_walls(pos, strip, walls, j, True)
        face, edge_a, edge_b = _pieces_held(depth, (a, b, reach), (j, projection.fix_len),
                                            grow, (eye, cones), k)
        if edge_b >= 0:
            k = edge_b
            proof[j] = _proof_code(PROOF_REACH, face, edge_a, edge_b)
            continue
        _work_out_walls(pos, strip, walls, j, False)
        face, edge_a, edge_b = _pieces_held(depth, (a, b, bottoms), (j, 0.0), grow,
                                            (eye, cones), k)
        if edge_b >= 0:
            k = edge_b
            proof[j] = _proof_code(PROOF_BOTTOMS, face, edge_a, edge_b)
            continue
        k = _row_held_in_pieces(pos, (a, b, bottoms), j, grow, (eye, cones), k, work)
        if k < 0:
            return -1
        proof[j] = _proof_code(PROOF_SPLITS, k, k, k)
    return k


@njit_without_refcounts
def _row_held_in_pieces(pos, strip, j, grow, shadows, first, work):
    """
    Return a sphere that held the last piece of rows j, j + 1 split as needed, or -1.

    The face between the edges, and each edge with its wall down to its bottoms, each
    held as quad_in_shadow holds a patch (split at most MAX_SPLITS deep). strip is
    (strands a, b, wall bottoms); shadows (eye, cones); first the sphere tried first.
    """
    a, b, bottoms = strip
    eye, cones = shadows
    rho = max(grow[0, j], grow[0, j + 1], grow[1, j], grow[1, j + 1])
    _set_quad(work, pos, a, pos, b, j)           # the face between the edges
    k = quad_in_shadow(work, rho, eye, cones, first)
    for q in range(2):                           # each edge with its wall
        if k < 0:
            return -1
        st = a if q == 0 else b
        _set_quad(work, pos, st, bottoms, st, j)
        k = quad_in_shadow(work, max(grow[q, j], grow[q, j + 1]), eye, cones, k)
    return k


def culling_scratch(pos_shape, n_occ, n_scalp):
    """
    Return visible_strips' scratch for strands shaped pos_shape, n_occ occluding spheres.

    Made once by the renderer: the kernel then makes no array. In order: the cones and
    which of them hold S; the walls' reach and bottoms (shaped like pos), which rows have
    them worked out and the projection's scratch; the deviations, the fix-up length
    everywhere, the wall extents, quad_in_shadow's pieces, the points and their depths;
    the candidate spheres, their cones and which of them hold S.
    """
    V = pos_shape[1]
    return (np.zeros((n_occ, 6)), np.zeros(n_occ, dtype=np.bool_),
            np.zeros(pos_shape), np.zeros(pos_shape), np.zeros((2, V), dtype=np.bool_),
            np.zeros((n_scalp, 2)),
            np.zeros((2, V)), np.zeros((2, V)), np.zeros((2, V)),
            np.zeros((SPLIT_ROWS, 13)), np.zeros((3, 2 * V)), np.zeros((n_occ, 2 * V)),
            np.zeros(n_occ, dtype=np.int64), np.zeros((n_occ, 6)),
            np.zeros(n_occ, dtype=np.bool_), np.zeros(V, dtype=np.int64))


@njit_without_refcounts
def visible_strips(pos,
                   strips,
                   projection,
                   view,
                   scratch,
                   out):
    """
    Write the strips that may be seen from the eye into out[:count], in order; return count.

    strips is (strip_strands, sigma, proof_rest, proofs), proof_rest (n_strips,) int64
    counting down the calls a strip whose proof failed is drawn without one, proofs
    (n_strips, V - 1) int64 the certificates of the strips proven hidden (certificate_holds;
    -1 in the first column: none), both kept by the caller from call to call (zeros, and
    -1, at first); view (eye, occluding spheres), both world;
    scratch culling_scratch's. The drawn edge of a strip is an Oslo refinement of its
    simulated edge polygon and lies within |second difference| / 6 of it (refined control
    polygons of a cubic B-spline stay between the control polygon and the curve); its wall
    runs down to bottoms close to those of the simulated vertices. Every corner ball is
    grown by the largest such deviation around it and MARGIN. How far the walls reach and
    their bottoms are worked out only for strips without a simulated vertex in plain view,
    and only where needed.
    """
    eye, occ = view
    (cones, holds_s, reach, bottoms, worked, spans, grow, fix_ups, extents, work, points,
     depth, candidates, candidate_cones, candidate_holds_s, row_sphere) = scratch
    shadow_cones_into(eye, occ, cones)
    holds_projection_sphere(projection, eye, cones, occ, holds_s)
    for q in range(2):
        for j in range(fix_ups.shape[1]):
            fix_ups[q, j] = projection.fix_len
    return _visible_strips_into(
        pos,
        strips,
        (projection, bottoms, reach, worked, spans),
        (eye, cones, holds_s),
        (grow, fix_ups, extents, work, points, depth),
        (candidates, candidate_cones, candidate_holds_s, row_sphere),
        out,
    )


@njit_without_refcounts
def _visible_strips_into(pos, strips, walls, shadows, scratch, candidates_scratch, out):
    """
    visible_strips, given its scratch: no array is made here (no reference counts).

    strips is (strip_strands, sigma, proof_rest, proofs); walls as _strip_hidden takes it;
    shadows (eye,
    cones, which spheres hold S); scratch (grow, the fix-up length everywhere (2, V),
    wall_extents, quad_in_shadow's pieces, points, depth); candidates_scratch (the
    candidate spheres, their cones and which of them hold S).
    """
    strip_strands, sigma, proof_rest, proofs = strips
    projection, bottoms, reach, worked, spans = walls
    eye, cones, holds_s = shadows
    grow, fix_ups, extents, work, points, depth = scratch
    candidates, candidate_cones, candidate_holds_s, row_sphere = candidates_scratch
    for j in range(row_sphere.shape[0]):
        row_sphere[j] = 0
    n_strips = strip_strands.shape[0]
    V = pos.shape[1]
    n_occ = cones.shape[0]
    last = 0                                     # the sphere that held the last piece
    fix = projection.fix_len
    count = 0
    for s in range(n_strips):
        if proof_rest[s] > 0:                    # its last proof failed: drawn unproven
            proof_rest[s] -= 1
            out[count] = s
            count += 1
            continue
        a, b = strip_strands[s, 0], strip_strands[s, 1]
        proof = proofs[s]
        if proof[0] >= 0:                        # proven hidden last call: check that
            held = certificate_holds(pos, (s, strip_strands, sigma[s]), proof, walls, shadows,
                                     (grow, fix_ups, extents), work)
            if held >= 0:
                last = held
                continue
            proof[0] = -1
        vis = False
        for q in range(2):                       # cheap and exact first
            st = a if q == 0 else b
            for j in range(V):
                hidden = False
                for i in range(n_occ):           # from the one that held this row last
                    k = _nth_sphere(row_sphere[j], i, n_occ)
                    if ball_in_shadow(pos[st, j, 0], pos[st, j, 1], pos[st, j, 2], 0.0, eye,
                                      cones, k):
                        hidden = True
                        last = k
                        row_sphere[j] = k
                        break
                if not hidden:
                    vis = True
                    break
            if vis:
                break
        if vis:
            out[count] = s
            count += 1
            continue
        # Every simulated vertex is in some shadow. The ball around them all (centre c):
        # a sphere that holds S and whose shadow holds that ball grown by the largest
        # deviation and the fix-up holds the whole strip with its walls (as
        # _held_with_any_walls); else the candidates are the spheres whose shadow reaches
        # the ball at all (by the depth's bound, shadow_depth)
        grow_max = _deviations(pos, (a, b), grow)
        cx, cy, cz = 0.0, 0.0, 0.0
        for q in range(2):
            st = a if q == 0 else b
            for j in range(V):
                cx += pos[st, j, 0]
                cy += pos[st, j, 1]
                cz += pos[st, j, 2]
        cx, cy, cz = cx / (2 * V), cy / (2 * V), cz / (2 * V)
        rr = 0.0
        for q in range(2):
            st = a if q == 0 else b
            for j in range(V):
                dx, dy, dz = pos[st, j, 0] - cx, pos[st, j, 1] - cy, pos[st, j, 2] - cz
                rr = max(rr, dx * dx + dy * dy + dz * dz)
        radius = sqrt(rr)
        nc = 0
        first = 0                                # the candidate that is `last`
        whole = -1
        for i in range(n_occ):
            k = _nth_sphere(last, i, n_occ)
            dc = shadow_depth(cx, cy, cz, eye, cones, k)
            if holds_s[k] and dc - radius >= grow_max + fix:
                whole = k
                break
            if dc + radius >= 0.0:
                if k == last:
                    first = nc
                candidates[nc] = k
                candidate_holds_s[nc] = holds_s[k]
                for d in range(6):
                    candidate_cones[nc, d] = cones[k, d]
                nc += 1
        if whole >= 0:                           # hidden, walls and all, at once
            last = whole
            for j in range(V - 1):
                proof[j] = _proof_code(PROOF_FIX_UP, whole, whole, whole)
            continue
        for q in range(2):
            st = a if q == 0 else b
            for j in range(V):
                for d in range(3):
                    points[d, q * V + j] = pos[st, j, d]
        near = candidate_cones[:nc]
        near_holds_s = candidate_holds_s[:nc]
        near_depth = depth[:nc]
        shadow_depths(points, 2 * V, eye, near, near_depth)
        held = _held_with_any_walls(near_depth, (0, V - 1), grow, fix_ups, near_holds_s,
                                    first)
        if held >= 0:
            for j in range(V - 1):
                proof[j] = _proof_code(PROOF_FIX_UP, held, held, held)
        else:                                    # not without working out the walls
            worked[:] = False
            held = _strip_hidden(pos,
                                 (s, strip_strands, sigma[s]),
                                 walls,
                                 (grow, fix_ups, extents),
                                 (eye, near, near_holds_s, near_depth),
                                 first,
                                 work,
                                 proof)
        if held >= 0:
            last = candidates[held]
            # the certificate, in the spheres' own numbers
            for j in range(V - 1):
                face, edge_a, edge_b = _proof_spheres(proof[j])
                proof[j] = _proof_code(proof[j] & 7, candidates[face], candidates[edge_a],
                                       candidates[edge_b])
        else:
            proof[0] = -1
            proof_rest[s] = PROOF_REST
            out[count] = s
            count += 1
    return count
