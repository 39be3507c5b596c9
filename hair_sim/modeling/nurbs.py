"""
NURBS basics: knot vectors, B-spline basis functions and de Boor evaluation.

These are the reference evaluations of the modeling stage (thesis ch. 6): the Oslo
refinement in `oslo.py` must reproduce the surfaces evaluated here.
"""

import numpy as np


def clamped_uniform_knots(n_ctrl, degree):
    """Return the clamped uniform knot vector on [0, 1] for n_ctrl points of degree p."""
    if degree < 1 or n_ctrl <= degree:
        raise ValueError('need degree >= 1 and more control points (%d) than the degree (%d)'
                         % (n_ctrl, degree))
    n_inner = n_ctrl - degree - 1
    inner = np.arange(1, n_inner + 1, dtype=np.float64) / (n_inner + 1)
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def check_knots(knots, n_ctrl, degree):
    """Return a reason string if `knots` is not a clamped knot vector for n_ctrl, else None."""
    knots = np.asarray(knots, dtype=np.float64)
    if knots.ndim != 1 or len(knots) != n_ctrl + degree + 1:
        return 'needs %d knots (control points + degree + 1), has %d' % (
            n_ctrl + degree + 1, knots.size)
    if not np.all(np.isfinite(knots)):
        return 'has a non-finite knot'
    if np.any(np.diff(knots) < 0):
        return 'is not non-decreasing'
    if np.any(knots[:degree + 1] != knots[0]) or np.any(knots[-degree - 1:] != knots[-1]):
        return 'is not clamped (first and last knots need multiplicity degree + 1)'
    if knots[-1] <= knots[0]:
        return 'has zero length'
    inner_mult = np.unique(knots[degree + 1:-degree - 1], return_counts=True)[1]
    if inner_mult.size and inner_mult.max() > degree:
        return 'has an inner knot of multiplicity above the degree'
    return None


def find_span(knots, degree, u):
    """Return the index mu of the knot span with knots[mu] <= u < knots[mu + 1]."""
    n = len(knots) - degree - 2          # index of the last control point
    if u >= knots[n + 1]:
        return n
    if u <= knots[degree]:
        return degree
    return int(np.searchsorted(knots, u, side='right') - 1)


def basis_functions(knots, degree, u):
    """Return (span, N) with N[r] = N_{span-p+r, p}(u), r = 0..p (Cox-de Boor)."""
    span = find_span(knots, degree, u)
    N = np.zeros(degree + 1)
    left = np.zeros(degree + 1)
    right = np.zeros(degree + 1)
    N[0] = 1.0
    for j in range(1, degree + 1):
        left[j] = u - knots[span + 1 - j]
        right[j] = knots[span + j] - u
        saved = 0.0
        for r in range(j):
            temp = N[r] / (right[r + 1] + left[j - r])
            N[r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        N[j] = saved
    return span, N


def de_boor(knots, degree, ctrl, u):
    """Evaluate a B-spline curve at u with de Boor's algorithm; ctrl is (n, d)."""
    ctrl = np.asarray(ctrl, dtype=np.float64)
    span = find_span(knots, degree, u)
    d = ctrl[span - degree:span + 1].copy()
    for r in range(1, degree + 1):
        for j in range(degree, r - 1, -1):
            i = span - degree + j
            denom = knots[i + degree - r + 1] - knots[i]
            a = 0.0 if denom == 0.0 else (u - knots[i]) / denom
            d[j] = (1.0 - a) * d[j - 1] + a * d[j]
    return d[degree]


def nurbs_curve_point(knots, degree, ctrl, weights, u):
    """Evaluate a NURBS curve at u by de Boor in homogeneous coordinates."""
    ctrl = np.asarray(ctrl, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    h = de_boor(knots, degree, np.column_stack([ctrl * w[:, None], w]), u)
    return h[:-1] / h[-1]


def nurbs_surface_point(knots_u, knots_v, degree_u, degree_v, net, weights, u, v):
    """
    Evaluate a NURBS surface at (u, v) by de Boor, first along v then across u.

    net is (n_u, n_v, 3): n_u control hairs across, n_v control points along each.
    """
    net = np.asarray(net, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    hom = np.concatenate([net * w[..., None], w[..., None]], axis=-1)
    rows = np.array([de_boor(knots_v, degree_v, hom[i], v) for i in range(hom.shape[0])])
    h = de_boor(knots_u, degree_u, rows, u)
    return h[:-1] / h[-1]
