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
    two divisions and one square root (a kernel of every U-shape wall row).
    """
    ux, uy, uz = o[0] - ax, o[1] - ay, o[2] - az
    dd = ux * ux + uy * uy + uz * uz
    if rs <= 0.0 or dd <= rs * rs:
        return o[0], o[1], o[2]
    inv_dd = 1.0 / dd
    wx, wy, wz = bx - ax, by - ay, bz - az
    along = (wx * ux + wy * uy + wz * uz) * inv_dd
    # y, unnormalised: AB less its part along U
    yx, yy, yz = wx - along * ux, wy - along * uy, wz - along * uz
    yy2 = yx * yx + yy * yy + yz * yz
    if yy2 < 1e-30:
        # AB along AO: any side will do (as vecmath.perpendicular_unit picks it)
        if abs(ux) < 0.9 * sqrt(dd):
            yx, yy, yz = 0.0, -uz, uy
        else:
            yx, yy, yz = uz, 0.0, -ux
        yy2 = yx * yx + yy * yy + yz * yz
    cb2 = (dd - rs * rs) * inv_dd                 # cos^2(beta)
    f = rs * sqrt(cb2 / yy2)                      # rs cos(beta) / |y|
    return ax + cb2 * ux - f * yx, ay + cb2 * uy - f * yy, az + cb2 * uz - f * yz


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
        # |w + t v|^2 < r^2, w = A - centre: the open interval between the roots
        b = wx * vx + wy * vy + wz * vz
        disc = b * b - vv * (ww - r * r)
        if disc <= 0.0:
            spans[k, 0], spans[k, 1] = 1.0, 0.0          # never inside
        else:
            sq = sqrt(disc)
            spans[k, 0], spans[k, 1] = (-b - sq) * inv_vv, (-b + sq) * inv_vv
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


@njit_without_refcounts
def ushape(grid,
           sigma,
           strips,
           projection,
           out,
           flags,
           spans):
    """
    Write the U-shape vertices of each strip into out (k, verts_per_strip, 3).

    Layout per strip: the grid column by column, then the left wall (edge column, its
    projections), then the right wall. sigma[s] = +1 when the strip's AB x AC normal faces
    the scalp side (fixed at rest), -1 otherwise. flags[k, side, r] = 0 projected on the
    scalp, 1 fixed because too far, 2 fixed because of reverse volume. spans (n_scalp, 2)
    is project_to_scalp's scratch.
    """
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
        for r in range(R):
            # one normal per row, for both walls
            r0, r1 = max(r - 1, 0), min(r + 1, R - 1)
            nx, ny, nz = strip_normal(_point(grid, k, 0, r), _point(grid, k, C - 1, r),
                                      _point(grid, k, 0, r0), _point(grid, k, C - 1, r0),
                                      _point(grid, k, 0, r1), _point(grid, k, C - 1, r1))
            nx, ny, nz = sg * nx, sg * ny, sg * nz              # towards the scalp side
            for side in range(2):
                ca = 0 if side == 0 else C - 1
                cb = C - 1 if side == 0 else 0
                ax, ay, az = grid[k, ca, r, 0], grid[k, ca, r, 1], grid[k, ca, r, 2]
                bx, by, bz = grid[k, cb, r, 0], grid[k, cb, r, 1], grid[k, cb, r, 2]
                tx, ty, tz = tangent_point(ax, ay, az, bx, by, bz, centre, rs)
                px, py, pz = project_to_scalp((ax, ay, az), (tx, ty, tz), scalp, delta, spans)
                vx, vy, vz = px - ax, py - ay, pz - az
                dist = sqrt(vx * vx + vy * vy + vz * vz)
                flag = 0
                if dist > max_dist:
                    flag = 1                                    # too far (fig. 3.4A)
                elif vx * nx + vy * ny + vz * nz < 0.0:
                    flag = 2                                    # reverse volume (fig. 3.7)
                if flag != 0:
                    px, py, pz = ax + fix_len * nx, ay + fix_len * ny, az + fix_len * nz
                flags[k, side, r] = flag
                base = C * R + side * 2 * R
                out[k, base + r, 0] = ax
                out[k, base + r, 1] = ay
                out[k, base + r, 2] = az
                out[k, base + R + r, 0] = px
                out[k, base + R + r, 1] = py
                out[k, base + R + r, 2] = pz


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
