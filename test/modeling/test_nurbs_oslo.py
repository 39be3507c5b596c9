"""Oslo refinement against de Boor, Boehm and the curve it must leave unchanged."""

import numpy as np
import pytest

from hair_sim.modeling.nurbs import (basis_functions, clamped_uniform_knots, de_boor,
                                     nurbs_curve_point, nurbs_surface_point)
from hair_sim.modeling.oslo import (boehm_insert, level_knots, oslo_matrix, oslo_refine_curve,
                                    oslo_refine_net, refined_knots)

RNG = np.random.default_rng(20031)


@pytest.mark.parametrize('degree', [1, 2, 3, 4])
def test_basis_functions_partition_unity_and_match_de_boor(degree):
    """B-spline basis sums to one; sum N_i c_i equals de Boor's evaluation."""
    n = 9
    knots = np.sort(np.concatenate([np.zeros(degree + 1), RNG.uniform(0, 1, n - degree - 1),
                                    np.ones(degree + 1)]))
    ctrl = RNG.normal(size=(n, 3))
    for u in RNG.uniform(0, 1, 200):
        span, N = basis_functions(knots, degree, u)
        assert abs(N.sum() - 1.0) < 1e-14
        assert np.all(N >= -1e-15)
        via_basis = N @ ctrl[span - degree:span + 1]
        assert np.abs(via_basis - de_boor(knots, degree, ctrl, u)).max() < 1e-13


@pytest.mark.parametrize('degree', [1, 2, 3])
def test_oslo_curve_unchanged_at_1000_parameters(degree):
    """A refined NURBS curve evaluates to the original at 1000 random parameters."""
    n = 7
    t = clamped_uniform_knots(n, degree)
    ctrl = RNG.normal(scale=0.1, size=(n, 3))
    w = RNG.uniform(0.5, 2.0, n)
    tau = refined_knots(t, degree, 31)
    new, new_w = oslo_refine_curve(t, degree, ctrl, tau, w)
    assert new.shape == (31, 3)
    dev = max(np.abs(nurbs_curve_point(tau, degree, new, new_w, u)
                     - nurbs_curve_point(t, degree, ctrl, w, u)).max()
              for u in RNG.uniform(0, 1, 1000))
    assert dev < 1e-12


def test_oslo_surface_unchanged_at_1000_parameters():
    """The refined NURBS net defines the same surface (max deviation < 1e-12 m)."""
    net = RNG.normal(scale=0.1, size=(6, 5, 3))
    w = RNG.uniform(0.5, 2.0, (6, 5))
    ku, kv = clamped_uniform_knots(6, 3), clamped_uniform_knots(5, 2)
    tu, tv = refined_knots(ku, 3, 40), refined_knots(kv, 2, 17)
    new, new_w = oslo_refine_net(net, w, ku, kv, 3, 2, tu, tv)
    assert new.shape == (40, 17, 3)
    dev = 0.0
    for u, v in RNG.uniform(0, 1, (1000, 2)):
        a = nurbs_surface_point(tu, tv, 3, 2, new, new_w, u, v)
        b = nurbs_surface_point(ku, kv, 3, 2, net, w, u, v)
        dev = max(dev, np.abs(a - b).max())
    assert dev < 1e-12


@pytest.mark.parametrize('degree', [2, 3])
def test_oslo_matches_boehm_insertion(degree):
    """Oslo's matrix gives the same control points as Boehm's one-knot-at-a-time insertion."""
    t = clamped_uniform_knots(8, degree)
    ctrl = RNG.normal(size=(8, 3))
    tau = refined_knots(t, degree, 25)
    oslo = oslo_matrix(t, tau, degree) @ ctrl
    tb, cb = t.copy(), ctrl.copy()
    for k in np.unique(tau):
        for _ in range(int((tau == k).sum() - (tb == k).sum())):
            tb, cb = boehm_insert(tb, degree, cb, k)
    np.testing.assert_array_equal(tb, tau)
    assert np.abs(cb - oslo).max() < 1e-13


@pytest.mark.parametrize('degree', [2, 3])
def test_oslo_full_multiplicity_point_is_de_boor_point(degree):
    """Inserting u `degree` times makes a refined control point equal to de Boor's C(u)."""
    t = clamped_uniform_knots(7, degree)
    ctrl = RNG.normal(size=(7, 3))
    for u in RNG.uniform(0.01, 0.99, 20):
        tau = np.sort(np.concatenate([t, np.full(degree, u)]))
        new = oslo_matrix(t, tau, degree) @ ctrl
        j = int(np.searchsorted(tau, u, side='left')) - 1
        assert np.abs(new[j] - de_boor(t, degree, ctrl, u)).max() < 1e-13


def test_refined_control_polygon_converges_monotonically():
    """Refinement levels 0..6 bring the control points monotonically closer to the surface."""
    degree = 3
    t = clamped_uniform_knots(6, degree)
    ctrl = np.array([[0, 0, 0], [0.05, 0.02, 0.0], [0.1, -0.03, 0.02], [0.15, 0.04, 0.0],
                     [0.2, 0.0, -0.03], [0.25, 0.02, 0.01]], dtype=float)
    errors = []
    for level in range(7):
        tau = level_knots(t, degree, level)
        new = oslo_matrix(t, tau, degree) @ ctrl
        greville = np.array([tau[j + 1:j + degree + 1].mean() for j in range(len(new))])
        on_curve = np.array([de_boor(t, degree, ctrl, g) for g in greville])
        errors.append(np.linalg.norm(new - on_curve, axis=1).max())
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    assert errors[-1] < errors[0] / 100        # about a quarter per level (O(h^2))


def test_refined_knots_are_nested():
    """More points never drop knots that fewer points had (refinement is nested)."""
    t = clamped_uniform_knots(5, 3)
    prev = t
    for n in range(6, 30):
        tau = refined_knots(t, 3, n)
        assert len(tau) == n + 4
        for k in np.unique(prev):
            assert (tau == k).sum() >= (prev == k).sum()
        prev = tau
    with pytest.raises(ValueError):
        refined_knots(t, 3, 4)
