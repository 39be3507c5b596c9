"""Head turns, translations and wind move the hair the way inertia and drag should."""

import numpy as np

from hair_sim import DEFAULT_DT, HairSimulator
from hair_sim.bench.scenarios import drive, quarter_turn, smoothstep, violent
from helpers.styles import settled

DT = DEFAULT_DT


def test_determinism(long_style):
    """The same inputs give bit-identical positions."""
    def run():
        sim = HairSimulator(long_style)
        sim.set_wind([2.0, 1.0, 0.0], turbulence=0.5, seed=3)
        drive(sim, violent, 0.0, 0.5, DT)
        return sim.strand_positions()
    a, b = run(), run()
    assert np.array_equal(a, b)


def test_head_turn_lags_and_recovers(long_style):
    """A 90 deg yaw in 0.3 s leaves tips >= 2 cm behind (head frame); back within 1 cm in 6 s."""
    sim = settled(long_style)
    tips0 = sim.positions_in_head_frame()[:, -1].copy()
    t0 = sim.time

    turn = quarter_turn(t0)
    t = drive(sim, turn, t0, 0.3, DT)
    lag = np.linalg.norm(sim.positions_in_head_frame()[:, -1] - tips0, axis=1).mean()
    assert lag >= 0.02, lag
    R, _ = sim.head_pose
    assert abs(R[1, 0] - 1.0) < 1e-9            # the head did turn by 90 degrees
    drive(sim, turn, t, 6.0, DT)
    back = np.linalg.norm(sim.positions_in_head_frame()[:, -1] - tips0, axis=1).mean()
    assert back < 0.01, back


def test_upward_translation_makes_tips_lag(long_style):
    """Accelerating the head upwards leaves the tips lower in the head frame, then recovers."""
    sim = settled(long_style)
    tips0 = sim.positions_in_head_frame()[:, -1].copy()
    t0 = sim.time

    def up(t):
        return np.array([0.0, 0.0, 0.15 * smoothstep((t - t0) / 0.25)]), np.array([0, 0, 0, 1.0])

    t = drive(sim, up, t0, 0.12, DT)                # peak upward acceleration
    dz = (sim.positions_in_head_frame()[:, -1] - tips0)[:, 2]
    assert dz.mean() < -3e-4, dz.mean()            # lower than at rest, on average
    drive(sim, up, t, 3.0, DT)
    dz = (sim.positions_in_head_frame()[:, -1] - tips0)[:, 2]
    assert abs(dz.mean()) < 1e-4


def test_steady_wind_deflects_tips_downwind_monotonically(long_style):
    """Tips move downwind, more for stronger wind, over four speeds."""
    shifts = []
    for speed in (1.0, 2.0, 4.0, 8.0):
        sim = settled(long_style)
        tips0 = sim.strand_positions()[:, -1].copy()
        sim.set_wind([0.0, speed, 0.0])
        assert not sim.sleeping
        for _ in range(int(2.0 / DT)):
            sim.step(DT)
        shifts.append((sim.strand_positions()[:, -1] - tips0)[:, 1].mean())
    assert shifts[0] > 0.002
    assert all(b > a for a, b in zip(shifts, shifts[1:])), shifts
