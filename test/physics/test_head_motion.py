"""Stamped head poses: jitter, repeats, out-of-order and jumping stamps, teleports."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hair_sim import DEFAULT_DT, HairSimulator
from hair_sim.bench.scenarios import drive, quarter_turn, quat_from_euler
from hair_sim.physics.motion import backlash
from helpers.styles import settled

ID = [0.0, 0.0, 0.0, 1.0]


def still_sim(style):
    """Return a settled simulator whose head was placed at the origin at t = 0."""
    sim = HairSimulator(style)
    assert sim.set_head_pose(0.0, [0, 0, 0], ID) == 'ok'
    while not sim.sleeping:
        sim.step(DEFAULT_DT)
    return sim


def test_repeated_and_out_of_order_stamps_are_dropped(long_style):
    """A repeated or older stamp is refused and counted; the hair does not move."""
    sim = still_sim(long_style)
    t = sim.time
    assert sim.set_head_pose(t, [0, 0, 0], ID) == 'ok'
    assert sim.set_head_pose(t, [0.3, 0, 0], ID) == 'repeated'
    assert sim.set_head_pose(t - 0.5, [0.3, 0, 0], ID) == 'out_of_order'
    before = sim.strand_positions()
    for _ in range(10):
        sim.step(DEFAULT_DT)
    assert np.array_equal(before, sim.strand_positions())
    assert sim.motion.counts['repeated'] == 1 and sim.motion.counts['out_of_order'] == 1


def test_invalid_and_unnormalised_poses(long_style):
    """NaN/inf and zero quaternions are refused; a scaled quaternion is normalised."""
    sim = still_sim(long_style)
    t = sim.time
    assert sim.set_head_pose(t + 0.01, [math.nan, 0, 0], ID) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], [0, 0, 0, 0]) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], [0, 0, math.inf, 1]) == 'invalid'
    assert sim.set_head_pose(math.nan, [0, 0, 0], ID) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, -math.inf, 0], ID) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], [math.nan, 0, 0, 1]) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 2e6], ID) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], [1e200, 0, 0, 1e200]) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0], ID) == 'invalid'
    assert sim.set_head_pose(math.inf, [0, 0, 0], ID) == 'invalid'
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], [0, 0, 0, 3.0]) == 'normalised'
    for _ in range(10):
        sim.step(DEFAULT_DT)
    assert np.all(np.isfinite(sim.strand_positions()))
    assert sim.motion.counts['invalid'] == 10


def test_teleport_carries_the_hair_rigidly(long_style):
    """A 10 m jump with a half turn moves the hair with the head: no swing, no NaN."""
    sim = still_sim(long_style)
    in_head = sim.positions_in_head_frame()
    t = sim.time + DEFAULT_DT
    assert sim.set_head_pose(t, [10.0, 0, 0], quat_from_euler(0, 0, math.pi)) == 'teleport'
    sim.step(DEFAULT_DT)
    R, p = sim.head_pose
    np.testing.assert_allclose(p, [10.0, 0, 0])
    np.testing.assert_allclose(sim.positions_in_head_frame(), in_head, atol=1e-3)
    for _ in range(int(1.0 / DEFAULT_DT)):
        sim.step(DEFAULT_DT)
    np.testing.assert_allclose(sim.positions_in_head_frame(), in_head, atol=1e-3)


def test_stamp_jumping_years_re_anchors_the_clock(long_style):
    """Stamps that jump years ahead re-anchor the mapping; motion goes on normally."""
    sim = still_sim(long_style)
    far = 3.0e7 + sim.time
    assert sim.set_head_pose(far, [0.0, 0.0, 0.0], ID) == 'clock_jump'
    assert sim.set_head_pose(far + 0.1, [0.0, 0.0, 0.01], ID) == 'ok'
    for _ in range(int(0.2 / DEFAULT_DT)):
        sim.step(DEFAULT_DT)
    _, p = sim.head_pose
    np.testing.assert_allclose(p, [0, 0, 0.01])


def test_jitter_is_smoothed(long_style):
    """A still head with +-1 mm, +-0.5 deg tracker noise at 100 Hz barely moves the hair."""
    sim = still_sim(long_style)
    tips = sim.strand_positions()[:, -1].copy()
    rng = np.random.default_rng(0)
    t = sim.time
    for _ in range(300):
        t += 0.01
        noise = rng.uniform(-0.001, 0.001, 3)
        rot = quat_from_euler(*rng.uniform(-0.009, 0.009, 3))
        sim.set_head_pose(t, noise, rot)
        for _ in range(int(round(0.01 / DEFAULT_DT * 1.2))):
            sim.step(0.01 / 2.4)
    moved = np.linalg.norm(sim.strand_positions()[:, -1] - tips, axis=1)
    assert np.all(np.isfinite(moved))
    assert moved.mean() < 0.004, moved.mean()
    assert sim.motion.counts['teleport'] == 0


def test_stamps_jumping_back_re_anchor_the_clock(long_style):
    """
    A looping bag: stamps 60 s back re-anchor (counted) and the head is followed again.

    A step back under clock_jump_back is only an out-of-order pose.
    """
    sim = still_sim(long_style)
    t = sim.time
    assert sim.set_head_pose(t + 0.01, [0, 0, 0], ID) == 'ok'
    assert sim.set_head_pose(t - 0.3, [0, 0, 0], ID) == 'out_of_order'
    assert sim.set_head_pose(t - 60.0, [0.05, 0, 0], ID) == 'clock_jump'
    assert sim.motion.counts['clock_jump'] == 1
    for i in range(1, 241):
        sim.set_head_pose(t - 60.0 + i / 240, [0.05, 0, 0], ID)
        sim.step(DEFAULT_DT)
    R, p = sim.head_pose
    assert np.allclose(p, [0.05, 0, 0]) and sim.motion.counts['accepted'] > 200
    stamp = sim.stamp_at()
    assert abs(stamp - (t - 60.0 + 1.0)) < 0.02       # output stamps follow the new clock
    sim.reset(clock=True)
    assert sim.motion.offset is None and sim.stamp_at() is None
    assert sim.set_head_pose(5.0, [0.05, 0, 0], ID) == 'ok'   # any clock is taken again


def test_rotation_vector_matches_scipy_including_half_turns():
    """The filter's axis-angle vector is scipy's, near the identity and near pi too."""
    import pytest
    from scipy.spatial.transform import Rotation
    from hair_sim.physics.motion import rotation_vector
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0.0, math.pi - 1e-3, 200), np.full(50, 1e-10),
                             math.pi - rng.uniform(0.0, 1e-7, 50)])
    for axis, angle in zip(axes, angles):
        r = Rotation.from_rotvec(axis * angle)
        got = rotation_vector(np.ascontiguousarray(r.as_matrix()))
        assert np.linalg.norm(got) == pytest.approx(angle, abs=1e-6)
        if angle > 3.1:                     # at pi the axis' sign is arbitrary
            assert min(np.linalg.norm(got - axis * angle),
                       np.linalg.norm(got + axis * angle)) < 1e-6
        else:
            assert np.allclose(got, axis * angle, atol=1e-9)


def test_head_filter_reaches_a_steady_turn_and_clamps_its_acceleration():
    """
    Under a steady turn the filtered w tends to the turn rate; a jump in it is clamped.

    The turn between the two poses (the fifth row) is the rate itself at every step.
    """
    from scipy.spatial.transform import Rotation
    from hair_sim.physics.motion import filter_head_motion
    h, rate, beta = 1.0 / 240, np.array([0.3, -1.2, 0.5]), 0.2
    p = np.zeros(3)
    R = np.eye(3)
    v, w = np.zeros(3), np.zeros(3)
    dR = Rotation.from_rotvec(rate * h).as_matrix()
    for k in range(400):
        R_new = np.ascontiguousarray(dR @ R)
        kin, moved = filter_head_motion((p, R_new), (p, R, v, w), beta, h, (1e9, 1e9))
        assert moved
        # the closed form of the low pass: w_k = rate (1 - (1 - beta)^k)
        assert np.allclose(kin[1], rate * (1.0 - (1.0 - beta) ** (k + 1)), atol=1e-9)
        assert np.allclose(kin[3], (kin[1] - w) / h)
        assert np.allclose(kin[4], rate, atol=1e-9)             # the turn itself, unfiltered
        v, w, R = kin[0], kin[1], R_new
    kin, moved = filter_head_motion((p + 0.01, R), (p, R, v, w), beta, h, (5.0, 7.0))
    assert abs(np.linalg.norm(kin[2]) - 5.0) < 1e-9             # 2.4 m/s in one step: clamped
    assert abs(np.linalg.norm(kin[3]) - 7.0) < 1e-9            # the turn stops: clamped
    kin, moved = filter_head_motion((p, R), (p, R, np.zeros(3), np.zeros(3)), beta, h,
                                    (5.0, 7.0))
    assert not moved and not kin.any()


@pytest.mark.parametrize('seed', range(6))
def test_backlash_holds_a_pose_inside_its_deadbands_and_moves_by_the_excess_beyond(seed):
    """Inside both deadbands the head stays; beyond, it ends exactly a deadband short."""
    rng = np.random.default_rng(seed)
    p0 = rng.normal(0.0, 0.1, 3)
    q0 = Rotation.random(random_state=seed).as_quat()
    band, turn_band = 0.01, 0.05
    near = p0 + 0.9 * band * _unit(rng.normal(size=3))
    slight = (Rotation.from_rotvec(0.9 * turn_band * _unit(rng.normal(size=3)))
              * Rotation.from_quat(q0)).as_quat()
    p, q, held = backlash(p0, q0, near, slight, band, turn_band)
    assert held == 1 and np.array_equal(p, p0) and np.array_equal(q, q0)
    far = p0 + rng.uniform(2.0, 20.0) * band * _unit(rng.normal(size=3))
    turned = (Rotation.from_rotvec(rng.uniform(1.5, 3.0) * _unit(rng.normal(size=3)))
              * Rotation.from_quat(q0)).as_quat()
    p, q, held = backlash(p0, q0, far, turned, band, turn_band)
    assert held == 0
    assert abs(np.linalg.norm(far - p) - band) < 1e-12
    assert abs(np.linalg.norm(np.cross(far - p0, p - p0))) < 1e-12       # straight at it
    short = (Rotation.from_quat(turned) * Rotation.from_quat(q).inv()).magnitude()
    assert abs(short - turn_band) < 1e-9
    moved = (Rotation.from_quat(q) * Rotation.from_quat(q0).inv()).magnitude()
    whole = (Rotation.from_quat(turned) * Rotation.from_quat(q0).inv()).magnitude()
    assert abs(moved + short - whole) < 1e-9                             # along the turn


def _unit(v):
    return v / np.linalg.norm(v)


@pytest.mark.parametrize('model', ['anjyo', 'articulated'])
def test_deadbands_let_hair_under_a_noisy_tracker_sleep(long_style, model):
    """
    Under a noisy tracker the hair sleeps with deadbands, and still follows a real turn.

    A still head seen by the tracker (2 mm, 0.4 degrees, 120 Hz): without deadbands the
    hair never sleeps; with them (5 sigma) it sleeps and stays put. A real turn moves it
    as it does without them, and the head then rests a turn deadband short of the pose.
    """
    rng = np.random.default_rng(1)
    noise = [(rng.normal(0.0, 2e-3, 3),
              Rotation.from_rotvec(rng.normal(0.0, math.radians(0.4), 3)).as_quat())
             for _ in range(600)]
    trails = []
    for band, turn_band in ((0.0, 0.0), (0.01, math.radians(2.0))):
        sim = settled(long_style, model=model, head_deadband=band, head_turn_deadband=turn_band)
        t = sim.time
        rest = sim.strand_positions()
        asleep, held = 0, sim.motion.counts['held']
        for p, q in noise:
            t += 1.0 / 120.0
            sim.set_head_pose(t, p, q)
            sim.step(1.0 / 240.0)
            sim.step(1.0 / 240.0)
            asleep += sim.sleeping
        if band == 0.0:
            assert asleep == 0
        else:
            assert asleep == len(noise) and sim.motion.counts['held'] - held == len(noise)
            assert np.array_equal(sim.strand_positions(), rest)
            assert np.array_equal(sim.head_pose[0], np.eye(3))
        sim = settled(long_style, model=model, head_deadband=band,   # a clean tracker
                      head_turn_deadband=turn_band)
        t = sim.time
        tips = sim.positions_in_head_frame()[:, -1]
        t_end = drive(sim, quarter_turn(t), t, 0.3, DEFAULT_DT)
        trails.append(np.linalg.norm(sim.positions_in_head_frame()[:, -1] - tips, axis=1))
        drive(sim, quarter_turn(t), t_end, 1.0, DEFAULT_DT)
        yaw = math.atan2(sim.head_pose[0][1, 0], sim.head_pose[0][0, 0])
        assert abs(yaw - (math.pi / 2 - turn_band)) < 1e-6, (yaw, turn_band)
    assert trails[0].mean() > 0.01                                  # the turn moved it
    assert abs(trails[1].mean() - trails[0].mean()) < 0.05 * trails[0].mean(), trails


def test_shifting_the_pose_clock_back_interpolates_poses_given_as_their_time_comes(long_style):
    """
    Poses given as the simulator's clock reaches their stamps hold the head between them.

    A head turning at 2 rad/s, a pose every 1/30 s given when the clock reaches it: the
    head moves in steps, standing still in 7 of every 8 steps of 1/240 s. With the pose
    clock shifted back a pose interval (shift_pose_clock, as the node's buffer does), the
    head turns in every step, by the turn's rate times the step, and the hair's stamps
    (stamp_at) trail the newest pose by the interval.
    """
    def turns(shift):
        sim = still_sim(long_style)
        t0 = sim.time
        sim.set_head_pose(t0, [0, 0, 0], ID)
        sim.step(DEFAULT_DT)
        sim.shift_pose_clock(shift)
        yaws, k = [], 0
        for i in range(240):
            while (k + 1) / 30.0 <= sim.time - t0 + 1e-9:        # its time has come
                k += 1
                sim.set_head_pose(t0 + k / 30.0, [0, 0, 0], quat_from_euler(0, 0, 2.0 * k / 30.0))
            sim.step(DEFAULT_DT)
            R, _ = sim.head_pose
            yaws.append(math.atan2(R[1, 0], R[0, 0]))
        return np.diff(np.unwrap(yaws))[30:], sim

    held, sim = turns(0.0)
    assert np.mean(np.abs(held) < 1e-9) > 0.8
    assert sim.stamp_at() == sim.motion.newest_stamp
    smooth, sim = turns(-1.0 / 30.0)
    assert np.allclose(smooth, 2.0 * DEFAULT_DT, rtol=1e-6)
    assert sim.motion.newest_stamp - sim.stamp_at() == pytest.approx(1.0 / 30.0, abs=DEFAULT_DT)


@pytest.mark.parametrize('bad', [float('nan'), float('inf'), 'x', None, [1.0]])
def test_a_pose_clock_shift_that_is_no_number_is_refused(long_style, bad):
    """shift_pose_clock refuses what is no finite number, and the mapping stays."""
    sim = still_sim(long_style)
    offset = sim.motion.offset
    with pytest.raises(ValueError):
        sim.shift_pose_clock(bad)
    assert sim.motion.offset == offset
