"""
The Oslo algorithm: refine a B-spline / NURBS control net by knot insertion (thesis 6.2).

Given a knot vector t and a refinement tau (a superset of t), the Oslo algorithm
(Cohen, Lyche and Riesenfeld 1980) computes the discrete B-splines alpha_{i,p}(j) so that
the refined control points are d_j = sum_i alpha_{i,p}(j) c_i and the curve is unchanged.
`oslo_matrix` returns that matrix; because it depends only on the knots, it is computed once
per level of detail and a refinement is then one small matrix product, every frame if need
be. `boehm_insert` is Boehm's one-knot-at-a-time insertion, kept as an independent second
method.
"""

import numpy as np


def oslo_matrix(t, tau, degree):
    """Return alpha (len(tau)-p-1, len(t)-p-1): refined control = alpha @ old control."""
    t = np.asarray(t, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    p = degree
    n_old = len(t) - p - 1
    n_new = len(tau) - p - 1
    alpha = np.zeros((n_new, n_old))
    for j in range(n_new):
        # mu: the old knot span holding tau_j (t_mu <= tau_j < t_mu+1, a non-empty span).
        mu = int(np.searchsorted(t, tau[j], side='right') - 1)
        mu = min(max(mu, p), n_old - 1)
        while mu > p and t[mu] == t[mu + 1]:
            mu -= 1
        # Discrete B-spline recurrence, degree 0 -> p, using tau_{j+1} .. tau_{j+p}.
        b = np.zeros(p + 1)          # b[r] = alpha_{mu-k+r, k}(j) at stage k
        b[0] = 1.0
        for k in range(1, p + 1):
            x = tau[j + k]
            nb = np.zeros(p + 1)
            for r in range(k + 1):
                i = mu - k + r
                acc = 0.0
                if r >= 1:           # alpha_{i,k-1}: weight from the left term
                    den = t[i + k] - t[i]
                    if den > 0.0:
                        acc += (x - t[i]) / den * b[r - 1]
                if r <= k - 1:       # alpha_{i+1,k-1}: weight from the right term
                    den = t[i + k + 1] - t[i + 1]
                    if den > 0.0:
                        acc += (t[i + k + 1] - x) / den * b[r]
                nb[r] = acc
            b = nb
        alpha[j, mu - p:mu + 1] = b
    return alpha


def refined_knots(t, degree, n_ctrl_new):
    """
    Return a refinement of the clamped knot vector t with n_ctrl_new control points.

    Knots are inserted one at a time at the middle of the currently longest span (ties go
    to the first), so refinements with more points contain those with fewer (nested).
    """
    t = np.asarray(t, dtype=np.float64)
    n_old = len(t) - degree - 1
    if n_ctrl_new < n_old:
        raise ValueError('refinement cannot lower the number of control points (%d < %d)'
                         % (n_ctrl_new, n_old))
    inner = list(t[degree + 1:len(t) - degree - 1])
    lo, hi = t[0], t[-1]
    for _ in range(n_ctrl_new - n_old):
        pts = [lo] + inner + [hi]
        gaps = np.diff(pts)
        k = int(np.argmax(gaps))
        inner.insert(k, 0.5 * (pts[k] + pts[k + 1]))
    return np.concatenate([np.full(degree + 1, lo), inner, np.full(degree + 1, hi)])


def level_knots(t, degree, level):
    """Return t refined by halving every non-empty span `level` times (a refinement level)."""
    t = np.asarray(t, dtype=np.float64)
    for _ in range(level):
        u = np.unique(t)
        mids = 0.5 * (u[:-1] + u[1:])
        t = np.sort(np.concatenate([t, mids]))
    return t


def oslo_refine_curve(t, degree, ctrl, tau, weights=None):
    """Refine a (NURBS) curve's control points from knots t to tau; returns (ctrl, weights)."""
    ctrl = np.asarray(ctrl, dtype=np.float64)
    alpha = oslo_matrix(t, tau, degree)
    if weights is None:
        return alpha @ ctrl, np.ones(alpha.shape[0])
    w = np.asarray(weights, dtype=np.float64)
    hw = alpha @ w
    return (alpha @ (ctrl * w[:, None])) / hw[:, None], hw


def oslo_refine_net(net, weights, knots_u, knots_v, degree_u, degree_v, tau_u, tau_v):
    """
    Refine a NURBS net across (u, over control hairs), then along (v), as thesis 6.2 does.

    net: (n_u, n_v, 3); weights: (n_u, n_v). Returns the refined (m_u, m_v, 3) net and
    its weights; the surface it defines with (tau_u, tau_v) is the original one.
    """
    net = np.asarray(net, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    hom = np.concatenate([net * w[..., None], w[..., None]], axis=-1)
    a_u = oslo_matrix(knots_u, tau_u, degree_u)
    a_v = oslo_matrix(knots_v, tau_v, degree_v)
    hom = np.einsum('ji,ivc->jvc', a_u, hom)          # across: connect control hairs
    hom = np.einsum('kv,jvc->jkc', a_v, hom)          # along: the tessellated columns
    return hom[..., :3] / hom[..., 3:], hom[..., 3]


def boehm_insert(t, degree, ctrl, u):
    """Insert the knot u once into a B-spline (Boehm 1980); returns (new knots, new ctrl)."""
    t = np.asarray(t, dtype=np.float64)
    ctrl = np.asarray(ctrl, dtype=np.float64)
    p = degree
    k = int(np.searchsorted(t, u, side='right') - 1)
    k = min(k, len(t) - p - 2)
    new = np.empty((ctrl.shape[0] + 1,) + ctrl.shape[1:])
    new[:k - p + 1] = ctrl[:k - p + 1]
    for i in range(k - p + 1, k + 1):
        a = (u - t[i]) / (t[i + p] - t[i])
        new[i] = (1.0 - a) * ctrl[i - 1] + a * ctrl[i]
    new[k + 1:] = ctrl[k:]
    return np.insert(t, k + 1, u), new
