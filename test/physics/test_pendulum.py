"""A single segment hanging from a fixed root against the analytic physical pendulum."""

import math

import numpy as np
import pytest

from hair_sim import DEFAULT_DT, HairSimulator, load_head, paths
from hair_sim.physics import PhysicsParams


def swing_period(integrator, length=0.03, dt=DEFAULT_DT, amplitude=0.02, periods=6):
    """Release a hanging segment from a small angle; return (measured, analytic) period."""
    head = load_head(paths.shipped_head('default_adult'))
    root = np.array([0.0, 0.0, 1.0])                       # far from every sphere
    rest = np.array([[root, root + [0.0, 0.0, -length]]])
    sim = HairSimulator.from_strands(rest, head, integrator=integrator, damping=0.0,
                                     collisions=False, inter_strip=False)
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    sim.set_directions([[[math.sin(amplitude), 0.0, -math.cos(amplitude)]]])  # at rest
    angles, times = [], []
    for i in range(int(periods * 0.2 / dt) + 200):
        sim.step(dt)
        d = sim.pos[0, 1] - sim.pos[0, 0]
        angles.append(math.copysign(math.acos(min(1.0, -d[2] / length)),
                                    d[0] if abs(d[0]) > abs(d[1]) else d[1]))
        times.append(sim.time)
    a, t = np.array(angles), np.array(times)
    up = np.flatnonzero((a[:-1] < 0) & (a[1:] >= 0))
    crossings = t[up] - a[up] * (t[up + 1] - t[up]) / (a[up + 1] - a[up])
    measured = np.diff(crossings).mean()
    p = PhysicsParams()
    m = p.linear_density * length
    inertia = m * length ** 2 / 3.0
    k = p.bending_stiffness / length
    analytic = 2 * math.pi * math.sqrt(inertia / (k + m * p.gravity * length / 2.0))
    return measured, analytic


@pytest.mark.parametrize('integrator', ['explicit', 'implicit'])
def test_period_matches_physical_pendulum_with_hinge_spring(integrator):
    """Small oscillations: T = 2 pi sqrt(I / (k + m g l / 2)) within 1 % at the default dt."""
    measured, analytic = swing_period(integrator)
    assert abs(measured - analytic) / analytic < 0.01, (measured, analytic)


def test_coarse_step_errs_more_than_default():
    """The error falls as dt falls (the comparison is not trivially satisfied)."""
    m_fine, a = swing_period('explicit', dt=DEFAULT_DT / 2)
    m_coarse, _ = swing_period('explicit', dt=DEFAULT_DT * 3)
    assert abs(m_fine - a) < abs(m_coarse - a)
