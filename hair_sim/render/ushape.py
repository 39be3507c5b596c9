"""
U-shape strips (thesis 3.1, 3.2): each drawn strip plus its two projections onto the scalp.

For every row of a tessellated strip the two edge vertices form the pair (A, B) of fig. 3.6.
A' is the point of the projection-centre sphere S, in the plane of A, B and S's centre O,
where the line from A touches S, on the side away from B (angle(AB, AO) < angle(AB, AA')).
Bisection between A and A' (threshold delta) finds the projection of A on the scalp, the
boundary of the union of the scalp spheres. A projection too far from A, or on the wrong
side of the strip (reverse volume, fig. 3.7: the angle between AA' and the strip normal
towards the scalp over 90 degrees), is replaced by A' = A + V, V along the strip normal,
towards the scalp side, of length C (fig. 3.4 B, D). Nothing of this is stored between
frames.
"""

from collections import namedtuple
from math import sqrt

import numpy as np

from hair_sim.kernels import njit_without_refcounts

# How the walls are projected (thesis 3.2): scalp spheres (world), the projection sphere's
# centre and radius rs (0: a point), the bisection tolerance delta, and the fix-up of a wall
# whose projection is farther than max_dist or reversed: fix_len along the strip normal.
Projection = namedtuple('Projection', ['scalp', 'centre', 'rs', 'delta', 'max_dist',
                                       'fix_len'])


@njit_without_refcounts
def tangent_point(ax, ay, az, bx, by, bz, o, rs):
    """
    Return A' on sphere S (centre o, radius rs) for the pair (A, B), fig. 3.6.

    With rs = 0 (a point as projection centre, fig. 3.3A) A' is O itself.

    With U = O - A, d = |U| and y the unit part of AB perpendicular to U (in the plane of
    A, B, O, towards B), AA' makes the angle beta = asin(rs / d) with U, turned away from
    B, and is as long as the tangent sqrt(d^2 - rs^2). So A' = A + cos^2(beta) U
    - rs cos(beta) y: written with d^2 and the length of y's unnormalised vector, that is
    two divisions and one square root (a kernel of every U-shape wall row). Selects, not
    branches, so that ushape's loop over the edges calling it is vectorised.
    """
    ux, uy, uz = o[0] - ax, o[1] - ay, o[2] - az
    dd = ux * ux + uy * uy + uz * uz
    at_centre = (rs <= 0.0) | (dd <= rs * rs)
    inv_dd = 1.0 / dd
    wx, wy, wz = bx - ax, by - ay, bz - az
    along = (wx * ux + wy * uy + wz * uz) * inv_dd
    # y, unnormalised: AB less its part along U
    yx, yy, yz = wx - along * ux, wy - along * uy, wz - along * uz
    yy2 = yx * yx + yy * yy + yz * yz
    # AB along AO: any side will do (as vecmath.perpendicular_unit picks it)
    along_ao = yy2 < 1e-30
    x_side = abs(ux) < 0.9 * sqrt(dd)
    yx = (0.0 if x_side else uz) if along_ao else yx
    yy = (-uz if x_side else 0.0) if along_ao else yy
    yz = (uy if x_side else -ux) if along_ao else yz
    yy2 = yx * yx + yy * yy + yz * yz if along_ao else yy2
    cb2 = (dd - rs * rs) * inv_dd                 # cos^2(beta)
    f = rs * sqrt(cb2 / yy2)                      # rs cos(beta) / |y|
    return (o[0] if at_centre else ax + cb2 * ux - f * yx,
            o[1] if at_centre else ay + cb2 * uy - f * yy,
            o[2] if at_centre else az + cb2 * uz - f * yz)


@njit_without_refcounts
def _span_in_sphere(w, ww, v, r):
    """
    Return the open interval of t with |w + t v| < r, or (1, 0) if there is none.

    w = A - the sphere's centre with ww = |w|^2; v = (v, |v|^2, 1 / |v|^2). The roots of
    |w + t v|^2 = r^2, without a branch (vectorised in ushape's phases).
    """
    vx, vy, vz, vv, inv_vv = v
    b = w[0] * vx + w[1] * vy + w[2] * vz
    disc = b * b - vv * (ww - r * r)
    sq = sqrt(disc)
    inside = disc > 0.0
    return ((-b - sq) * inv_vv if inside else 1.0), ((-b + sq) * inv_vv if inside else 0.0)


@njit_without_refcounts
def project_to_scalp(a, target, scalp, delta, spans):
    """
    Bisect from A (outside) towards A' (inside) until |XY| <= delta (thesis 3.2).

    Returns the midpoint of the final X and Y, within delta / 2 of the boundary like X, so
    that a vertex already on the scalp (a root) still gets a wall of non-zero depth.
    A vertex deeper than delta inside the scalp is its own projection.

    The bisection runs on the parameter t of A + t (A' - A): where that segment is inside
    each scalp sphere is an interval of t (one square root per sphere, written into the
    scratch array spans (n_scalp, 2)), so a midpoint's test is a few comparisons instead
    of a distance to every sphere. The midpoints and the result are those of the bisection
    between the points (to rounding).
    """
    ax, ay, az = a
    vx, vy, vz = target[0] - ax, target[1] - ay, target[2] - az
    vv = vx * vx + vy * vy + vz * vz
    inv_vv = 1.0 / vv if vv != 0.0 else 0.0
    for k in range(scalp.shape[0]):
        wx, wy, wz = ax - scalp[k, 0], ay - scalp[k, 1], az - scalp[k, 2]
        ww = wx * wx + wy * wy + wz * wz
        r = scalp[k, 3]
        deep = r - delta
        if ww < deep * deep:
            return ax, ay, az                   # deeper than delta inside: its own projection
        spans[k, 0], spans[k, 1] = _span_in_sphere((wx, wy, wz), ww, (vx, vy, vz, vv, inv_vv),
                                                   r)
    if vv == 0.0:
        return ax, ay, az
    # the bisection halves [0, 1] n times, n the first with (2^-n)^2 |AA'|^2 <= delta^2
    width = 1.0
    scale = 1.0                   # 1 / width, a power of two like it: exact
    d2 = delta * delta
    while width * width * vv > d2:
        width *= 0.5
        scale *= 2.0
    # Entering the union once and staying in up to A' (the usual case), the midpoints
    # compare with the entry t*: the last bracket is the dyadic one holding t*.
    entry = 1.0
    for k in range(scalp.shape[0]):
        if spans[k, 1] > 0.0 and spans[k, 0] < entry:
            entry = max(spans[k, 0], 0.0)
    cover = entry
    grown = True
    while grown and cover < 1.0:
        grown = False
        for k in range(scalp.shape[0]):
            if spans[k, 0] <= cover < spans[k, 1]:
                cover = spans[k, 1]
                grown = True
    if cover >= 1.0 and 0.0 < entry < 1.0:
        # (a midpoint exactly at t* is outside: X moves onto it, as floor has it)
        t = (np.floor(entry * scale) + 0.5) * width
        return ax + t * vx, ay + t * vy, az + t * vz
    lo, hi = 0.0, 1.0            # in and out again: the bisection itself
    while (hi - lo) * (hi - lo) * vv > d2:
        mid = 0.5 * (lo + hi)
        inside = False
        for k in range(scalp.shape[0]):
            if spans[k, 0] < mid < spans[k, 1]:
                inside = True
                break
        if inside:
            hi = mid
        else:
            lo = mid
    t = 0.5 * (lo + hi)
    return ax + t * vx, ay + t * vy, az + t * vz


@njit_without_refcounts
def tessellate_strips(pos, strip_strands, strips, along, across, out_grid):
    """Refine the simulated net of each listed strip to its (columns, rows, 3) grid."""
    R, V = along.shape
    C = across.shape[0]
    for k in range(strips.shape[0]):
        s = strips[k]
        a, b = strip_strands[s, 0], strip_strands[s, 1]
        for r in range(R):
            ex0 = ey0 = ez0 = ex1 = ey1 = ez1 = 0.0
            for v in range(V):
                w = along[r, v]
                if w != 0.0:
                    ex0 += w * pos[a, v, 0]
                    ey0 += w * pos[a, v, 1]
                    ez0 += w * pos[a, v, 2]
                    ex1 += w * pos[b, v, 0]
                    ey1 += w * pos[b, v, 1]
                    ez1 += w * pos[b, v, 2]
            for c in range(C):
                w0, w1 = across[c, 0], across[c, 1]
                out_grid[k, c, r, 0] = w0 * ex0 + w1 * ex1
                out_grid[k, c, r, 1] = w0 * ey0 + w1 * ey1
                out_grid[k, c, r, 2] = w0 * ez0 + w1 * ez1


@njit_without_refcounts
def _point(grid, k, c, r):
    """
    Return grid[k, c, r] as a tuple (x, y, z).

    A view of the array per row would cost an atomic reference-count pair each (numba's
    runtime); the kernels here pass points as tuples.
    """
    return grid[k, c, r, 0], grid[k, c, r, 1], grid[k, c, r, 2]


@njit_without_refcounts
def _vertex(pos, s, j):
    """Return pos[s, j] as a tuple (x, y, z) (see _point)."""
    return pos[s, j, 0], pos[s, j, 1], pos[s, j, 2]


@njit_without_refcounts
def strip_normal(left, right, left_prev, right_prev, left_next, right_next):
    """
    Return the unit normal AB x AC of a strip's row (0 if degenerate), thesis 3.1.

    A is the row's left edge, B its right edge, C the direction down the strip: the mean
    of both edges' central differences between the previous and next rows.
    """
    bx = right[0] - left[0]
    by = right[1] - left[1]
    bz = right[2] - left[2]
    cx = 0.5 * (left_next[0] + right_next[0] - left_prev[0] - right_prev[0])
    cy = 0.5 * (left_next[1] + right_next[1] - left_prev[1] - right_prev[1])
    cz = 0.5 * (left_next[2] + right_next[2] - left_prev[2] - right_prev[2])
    nx, ny, nz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    n = sqrt(nx * nx + ny * ny + nz * nz)
    if n < 1e-18:
        return 0.0, 0.0, 0.0
    return nx / n, ny / n, nz / n


# The walls of a strip are projected WALL_ROWS rows (2 WALL_ROWS edge vertices A) at a
# time, phase by phase, each phase a loop over the edges that LLVM vectorises (no call, no
# early return, rows at constant offsets of a scratch): the tangent point A', the span of
# A + t (A' - A) inside each scalp sphere, the bisection's width, entry and cover, and the
# fix-ups. Edges off the usual path (deep inside the scalp, A' = A, or in and out of the
# scalp again: 278 of 10 800 in a 180-strip demo frame) are marked and projected by
# project_to_scalp itself. Every number is computed by the same
# operations in the same order as there, so the walls are the same to the bit.
WALL_ROWS = 128
WALL_EDGES = 2 * WALL_ROWS
# rows of the scratch: A, B (the row's other edge), the strip normal towards the scalp,
# V = A' - A, |V|^2 and its inverse, the bisection's entry, cover, width and 1 / width,
# 1 where the edge takes the exact path, the projection P and its fix-up flag
(WALL_AX, WALL_AY, WALL_AZ, WALL_BX, WALL_BY, WALL_BZ, WALL_NX, WALL_NY, WALL_NZ,
 WALL_VX, WALL_VY, WALL_VZ, WALL_VV, WALL_INV_VV, WALL_ENTRY, WALL_COVER, WALL_WIDTH,
 WALL_SCALE, WALL_EXACT, WALL_PX, WALL_PY, WALL_PZ, WALL_FLAG) = range(23)
WALL_FIELDS = 23


def wall_scratch(n_scalp):
    """Return ushape's scratch: project_to_scalp's spans, the walls' rows, their spans."""
    return (np.empty((n_scalp, 2)), np.zeros(WALL_FIELDS * WALL_EDGES),
            np.zeros(2 * n_scalp * WALL_EDGES))


@njit_without_refcounts
def _tangent_points(walls,
                    n,
                    centre,
                    rs):
    """
    Phase of ushape: V = A' - A of every edge (tangent_point), |V|^2 and 1 / |V|^2.

    Marks A' = A (project_to_scalp returns A) for the exact path.
    """
    for e in range(n):
        ax = walls[WALL_AX * WALL_EDGES + e]
        ay = walls[WALL_AY * WALL_EDGES + e]
        az = walls[WALL_AZ * WALL_EDGES + e]
        tx, ty, tz = tangent_point(ax, ay, az, walls[WALL_BX * WALL_EDGES + e],
                                   walls[WALL_BY * WALL_EDGES + e],
                                   walls[WALL_BZ * WALL_EDGES + e], centre, rs)
        vx, vy, vz = tx - ax, ty - ay, tz - az
        vv = vx * vx + vy * vy + vz * vz
        walls[WALL_VX * WALL_EDGES + e] = vx
        walls[WALL_VY * WALL_EDGES + e] = vy
        walls[WALL_VZ * WALL_EDGES + e] = vz
        walls[WALL_VV * WALL_EDGES + e] = vv
        walls[WALL_INV_VV * WALL_EDGES + e] = 1.0 / vv if vv != 0.0 else 0.0
        walls[WALL_EXACT * WALL_EDGES + e] = 1.0 if vv == 0.0 else 0.0


@njit_without_refcounts
def _scalp_spans(walls,
                 spans,
                 n,
                 scalp,
                 delta):
    """
    Phase of ushape: each edge's span (lo, hi) of t inside each scalp sphere (spans rows).

    project_to_scalp's arithmetic; an A deeper than delta inside a sphere is marked for the
    exact path (there it is its own projection).
    """
    for k in range(scalp.shape[0]):
        cx, cy, cz, r = scalp[k, 0], scalp[k, 1], scalp[k, 2], scalp[k, 3]
        deep = r - delta
        lo_row = 2 * k * WALL_EDGES
        hi_row = lo_row + WALL_EDGES
        for e in range(n):
            wx = walls[WALL_AX * WALL_EDGES + e] - cx
            wy = walls[WALL_AY * WALL_EDGES + e] - cy
            wz = walls[WALL_AZ * WALL_EDGES + e] - cz
            vx = walls[WALL_VX * WALL_EDGES + e]
            vy = walls[WALL_VY * WALL_EDGES + e]
            vz = walls[WALL_VZ * WALL_EDGES + e]
            vv = walls[WALL_VV * WALL_EDGES + e]
            inv_vv = walls[WALL_INV_VV * WALL_EDGES + e]
            ww = wx * wx + wy * wy + wz * wz
            spans[lo_row + e], spans[hi_row + e] = _span_in_sphere(
                (wx, wy, wz), ww, (vx, vy, vz, vv, inv_vv), r)
            if ww < deep * deep:
                walls[WALL_EXACT * WALL_EDGES + e] = 1.0


@njit_without_refcounts
def _bisection_widths(walls,
                      n,
                      delta):
    """
    Phase of ushape: the width 2^-m of the bisection's last bracket and 2^m (exact).

    m is the first with (2^-m)^2 |V|^2 <= delta^2: halvings over every edge until none
    needs another (the loop of project_to_scalp, edge by edge the same numbers).
    """
    d2 = delta * delta
    for e in range(n):
        walls[WALL_WIDTH * WALL_EDGES + e] = 1.0
        walls[WALL_SCALE * WALL_EDGES + e] = 1.0
    more = 1
    while more > 0:
        more = 0
        for e in range(n):
            width = walls[WALL_WIDTH * WALL_EDGES + e]
            halve = width * width * walls[WALL_VV * WALL_EDGES + e] > d2
            walls[WALL_WIDTH * WALL_EDGES + e] = width * 0.5 if halve else width
            scale = walls[WALL_SCALE * WALL_EDGES + e]
            walls[WALL_SCALE * WALL_EDGES + e] = scale * 2.0 if halve else scale
            more += 1 if halve else 0


@njit_without_refcounts
def _projections(walls,
                 spans,
                 n,
                 n_scalp):
    """
    Phase of ushape: P of every edge that enters the scalp once and stays in up to A'.

    Entry and cover as project_to_scalp takes them, sphere by sphere (cover: as many
    passes over the spheres as can grow it, n_scalp + 1); P = A + t V with t the middle
    of the dyadic bracket holding the entry. Other edges are marked for the exact path.
    """
    for e in range(n):
        walls[WALL_ENTRY * WALL_EDGES + e] = 1.0
    for k in range(n_scalp):
        lo_row = 2 * k * WALL_EDGES
        hi_row = lo_row + WALL_EDGES
        for e in range(n):
            lo = spans[lo_row + e]
            entry = walls[WALL_ENTRY * WALL_EDGES + e]
            walls[WALL_ENTRY * WALL_EDGES + e] = max(lo, 0.0) if (spans[hi_row + e] > 0.0) & \
                (lo < entry) else entry
    for e in range(n):
        walls[WALL_COVER * WALL_EDGES + e] = walls[WALL_ENTRY * WALL_EDGES + e]
    for _ in range(n_scalp + 1):
        for k in range(n_scalp):
            lo_row = 2 * k * WALL_EDGES
            hi_row = lo_row + WALL_EDGES
            for e in range(n):
                cover = walls[WALL_COVER * WALL_EDGES + e]
                hi = spans[hi_row + e]
                walls[WALL_COVER * WALL_EDGES + e] = hi if (spans[lo_row + e] <= cover) & \
                    (cover < hi) else cover
    for e in range(n):
        entry = walls[WALL_ENTRY * WALL_EDGES + e]
        once = (walls[WALL_COVER * WALL_EDGES + e] >= 1.0) & (0.0 < entry) & (entry < 1.0)
        t = (np.floor(entry * walls[WALL_SCALE * WALL_EDGES + e]) + 0.5) * \
            walls[WALL_WIDTH * WALL_EDGES + e]
        walls[WALL_PX * WALL_EDGES + e] = walls[WALL_AX * WALL_EDGES + e] + \
            t * walls[WALL_VX * WALL_EDGES + e]
        walls[WALL_PY * WALL_EDGES + e] = walls[WALL_AY * WALL_EDGES + e] + \
            t * walls[WALL_VY * WALL_EDGES + e]
        walls[WALL_PZ * WALL_EDGES + e] = walls[WALL_AZ * WALL_EDGES + e] + \
            t * walls[WALL_VZ * WALL_EDGES + e]
        if not once:
            walls[WALL_EXACT * WALL_EDGES + e] = 1.0


@njit_without_refcounts
def _fix_ups(walls,
             n,
             max_dist,
             fix_len):
    """Phase of ushape: a projection too far (1) or reversed (2) goes to A + fix_len N."""
    for e in range(n):
        ax = walls[WALL_AX * WALL_EDGES + e]
        ay = walls[WALL_AY * WALL_EDGES + e]
        az = walls[WALL_AZ * WALL_EDGES + e]
        nx = walls[WALL_NX * WALL_EDGES + e]
        ny = walls[WALL_NY * WALL_EDGES + e]
        nz = walls[WALL_NZ * WALL_EDGES + e]
        px = walls[WALL_PX * WALL_EDGES + e]
        py = walls[WALL_PY * WALL_EDGES + e]
        pz = walls[WALL_PZ * WALL_EDGES + e]
        vx, vy, vz = px - ax, py - ay, pz - az
        dist = sqrt(vx * vx + vy * vy + vz * vz)
        far = dist > max_dist
        reverse = vx * nx + vy * ny + vz * nz < 0.0
        fixed = far | reverse
        walls[WALL_PX * WALL_EDGES + e] = ax + fix_len * nx if fixed else px
        walls[WALL_PY * WALL_EDGES + e] = ay + fix_len * ny if fixed else py
        walls[WALL_PZ * WALL_EDGES + e] = az + fix_len * nz if fixed else pz
        walls[WALL_FLAG * WALL_EDGES + e] = 1.0 if far else (2.0 if reverse else 0.0)


@njit_without_refcounts
def ushape(grid,
           sigma,
           strips,
           projection,
           out,
           flags,
           scratch):
    """
    Write the U-shape vertices of each strip into out (k, verts_per_strip, 3).

    Layout per strip: the grid column by column, then the left wall (edge column, its
    projections), then the right wall. sigma[s] = +1 when the strip's AB x AC normal faces
    the scalp side (fixed at rest), -1 otherwise. flags[k, side, r] = 0 projected on the
    scalp, 1 fixed because too far, 2 fixed because of reverse volume. scratch is
    wall_scratch(n_scalp): the walls are projected WALL_ROWS rows at a time by vectorised
    phases (see WALL_ROWS), the rest by project_to_scalp.
    """
    spans, walls, sphere_spans = scratch
    scalp, centre, rs, delta = (projection.scalp, projection.centre, projection.rs,
                                projection.delta)
    max_dist, fix_len = projection.max_dist, projection.fix_len
    K, C, R = grid.shape[0], grid.shape[1], grid.shape[2]
    for k in range(K):
        sg = sigma[strips[k]]
        i = 0
        for c in range(C):
            for r in range(R):
                out[k, i, 0] = grid[k, c, r, 0]
                out[k, i, 1] = grid[k, c, r, 1]
                out[k, i, 2] = grid[k, c, r, 2]
                i += 1
        for r0 in range(0, R, WALL_ROWS):
            rows = min(WALL_ROWS, R - r0)
            n = 2 * rows
            for rr in range(rows):
                r = r0 + rr
                # one normal per row, for both walls
                r_prev, r_next = max(r - 1, 0), min(r + 1, R - 1)
                nx, ny, nz = strip_normal(_point(grid, k, 0, r), _point(grid, k, C - 1, r),
                                          _point(grid, k, 0, r_prev),
                                          _point(grid, k, C - 1, r_prev),
                                          _point(grid, k, 0, r_next),
                                          _point(grid, k, C - 1, r_next))
                for side in range(2):
                    e = 2 * rr + side
                    ca = 0 if side == 0 else C - 1
                    cb = C - 1 if side == 0 else 0
                    for a in range(3):
                        walls[(WALL_AX + a) * WALL_EDGES + e] = grid[k, ca, r, a]
                        walls[(WALL_BX + a) * WALL_EDGES + e] = grid[k, cb, r, a]
                    walls[WALL_NX * WALL_EDGES + e] = sg * nx      # towards the scalp side
                    walls[WALL_NY * WALL_EDGES + e] = sg * ny
                    walls[WALL_NZ * WALL_EDGES + e] = sg * nz
            _tangent_points(walls, n, centre, rs)
            _scalp_spans(walls, sphere_spans, n, scalp, delta)
            _bisection_widths(walls, n, delta)
            _projections(walls, sphere_spans, n, scalp.shape[0])
            for e in range(n):
                if walls[WALL_EXACT * WALL_EDGES + e] != 0.0:
                    a = (walls[WALL_AX * WALL_EDGES + e], walls[WALL_AY * WALL_EDGES + e],
                         walls[WALL_AZ * WALL_EDGES + e])
                    t = tangent_point(a[0], a[1], a[2], walls[WALL_BX * WALL_EDGES + e],
                                      walls[WALL_BY * WALL_EDGES + e],
                                      walls[WALL_BZ * WALL_EDGES + e], centre, rs)
                    px, py, pz = project_to_scalp(a, t, scalp, delta, spans)
                    walls[WALL_PX * WALL_EDGES + e] = px
                    walls[WALL_PY * WALL_EDGES + e] = py
                    walls[WALL_PZ * WALL_EDGES + e] = pz
            _fix_ups(walls, n, max_dist, fix_len)
            for rr in range(rows):
                r = r0 + rr
                for side in range(2):
                    e = 2 * rr + side
                    flags[k, side, r] = np.int64(walls[WALL_FLAG * WALL_EDGES + e])
                    base = C * R + side * 2 * R
                    for a in range(3):
                        out[k, base + r, a] = walls[(WALL_AX + a) * WALL_EDGES + e]
                        out[k, base + R + r, a] = walls[(WALL_PX + a) * WALL_EDGES + e]


@njit_without_refcounts
def strip_wall_reach(pos,
                     strip_strands,
                     s,
                     projection,
                     rows,
                     out):
    """
    Write how far the U-shape walls below strip s's simulated vertices can reach.

    A wall's bottom (strip_wall_bottoms) is on the segment from its edge point A to A'
    (tangent_point) within max_dist of A, or else it is the fix-up, fix_len from A. So
    the wall lies in the hull of the ball of radius fix_len around A and the segment from
    A to out[a, j]: A + min(1, max_dist / |AA'|) (A' - A), without the bisection. Where
    that segment, lengthened by delta, meets no scalp sphere grown by delta, the
    bisection's point (within delta of where AA' enters the scalp) is farther than
    max_dist and the wall is the fix-up: out[a, j] = A. Rows j0..j1 (rows = (j0, j1),
    inclusive).
    """
    scalp, centre, rs = projection.scalp, projection.centre, projection.rs
    delta, max_dist = projection.delta, projection.max_dist
    l0, l1 = strip_strands[s, 0], strip_strands[s, 1]
    for j in range(rows[0], rows[1] + 1):
        for side in range(2):
            a = l0 if side == 0 else l1
            b = l1 if side == 0 else l0
            ax, ay, az = pos[a, j, 0], pos[a, j, 1], pos[a, j, 2]
            tx, ty, tz = tangent_point(ax, ay, az, pos[b, j, 0], pos[b, j, 1], pos[b, j, 2],
                                       centre, rs)
            vx, vy, vz = tx - ax, ty - ay, tz - az
            vv = vx * vx + vy * vy + vz * vz
            length = sqrt(vv)
            inv_len = 1.0 / length if vv > 0.0 else 0.0      # (one division for the three)
            f = max_dist * inv_len if length > max_dist else 1.0
            # does A + t (A' - A), 0 <= t <= (max_dist + delta) / |AA'|, meet the scalp?
            # (the point of the segment nearest each sphere's centre is inside it)
            t_end = (max_dist + delta) * inv_len
            inv_vv = inv_len * inv_len
            meets = False
            for k in range(scalp.shape[0]):
                wx, wy, wz = ax - scalp[k, 0], ay - scalp[k, 1], az - scalp[k, 2]
                t = min(max(-(wx * vx + wy * vy + wz * vz) * inv_vv, 0.0), t_end)
                cx, cy, cz = wx + t * vx, wy + t * vy, wz + t * vz
                r = scalp[k, 3] + delta
                meets |= cx * cx + cy * cy + cz * cz <= r * r
            if not meets:
                f = 0.0
            out[a, j, 0] = ax + f * vx
            out[a, j, 1] = ay + f * vy
            out[a, j, 2] = az + f * vz


@njit_without_refcounts
def strip_wall_bottoms(pos,
                       strip_strands,
                       s,
                       sigma_s,
                       projection,
                       rows,
                       out,
                       spans):
    """
    Write where the U-shape walls below strip s's simulated vertices end (fix-ups too).

    Rows j0..j1 (rows = (j0, j1), inclusive); spans (n_scalp, 2) is project_to_scalp's
    scratch.
    """
    scalp, centre, rs, delta = (projection.scalp, projection.centre, projection.rs,
                                projection.delta)
    max_dist, fix_len = projection.max_dist, projection.fix_len
    V = pos.shape[1]
    l0, l1 = strip_strands[s, 0], strip_strands[s, 1]
    for j in range(rows[0], rows[1] + 1):
        # the strip normal AB x AC with A the left edge, as ushape() takes it; one a row
        j0, j1 = max(j - 1, 0), min(j + 1, V - 1)
        nx, ny, nz = strip_normal(_vertex(pos, l0, j), _vertex(pos, l1, j),
                                  _vertex(pos, l0, j0), _vertex(pos, l1, j0),
                                  _vertex(pos, l0, j1), _vertex(pos, l1, j1))
        nx, ny, nz = sigma_s * nx, sigma_s * ny, sigma_s * nz
        for side in range(2):
            a = l0 if side == 0 else l1
            b = l1 if side == 0 else l0
            ax, ay, az = pos[a, j, 0], pos[a, j, 1], pos[a, j, 2]
            tx, ty, tz = tangent_point(ax, ay, az, pos[b, j, 0], pos[b, j, 1], pos[b, j, 2],
                                       centre, rs)
            px, py, pz = project_to_scalp((ax, ay, az), (tx, ty, tz), scalp, delta, spans)
            vx, vy, vz = px - ax, py - ay, pz - az
            if vx * vx + vy * vy + vz * vz > max_dist * max_dist or \
                    vx * nx + vy * ny + vz * nz < 0.0:
                px, py, pz = ax + fix_len * nx, ay + fix_len * ny, az + fix_len * nz
            out[a, j, 0] = px
            out[a, j, 1] = py
            out[a, j, 2] = pz
