"""
The thesis model's kernels one by one, against closed forms (PyElastica's shape of test).

Chart re-centring keeps every direction it re-expresses; eq. 4's moments are the virtual
work of the forces; the eq. 6 update and its implicit variant follow the closed-form
solution of their own recurrences; the position guard turns an end out of the sphere at
the segment's length, in its own plane, and a guarded strand keeps its segment lengths.
The step's vectorised pieces: its branch-free atan2 against libm's (numpy's), and its
blocks of segments, which cut strands anywhere, against each strand stepped alone.
"""

import math

from numba import njit
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hair_sim.physics.forces import GUARD_MARGIN, guard_rest_shape, guard_segment
from hair_sim.physics.solvers.anjyo import (_direction, _moments_of_trig, _next_deviation,
                                            _recentre, BLOCK, EXPLICIT, IMPLICIT, POLE_COS,
                                            W_NEXT, W_NOW, W_PREV)
from hair_sim.vecmath import atan2_vectorizable, sin_vectorizable


def random_chart(rng):
    """Return a random chart as the kernels take it: its x, y, z axes (world), row by row."""
    return tuple(Rotation.random(random_state=rng).as_matrix().T.ravel())


@pytest.mark.parametrize('seed', range(6))
def test_recentre_keeps_directions_and_leaves_the_pole(seed):
    """A segment near its chart's pole is re-expressed in a chart where it is not."""
    rng = np.random.default_rng(seed)
    C = random_chart(rng)
    th, ph = 0.05 + 0.1 * rng.random(), 2 * math.pi * rng.random()
    thp, php = th + 0.01, ph - 0.02
    rest = np.array(_direction(C, 0.3, 1.0))
    before = [np.array(_direction(C, th, ph)), np.array(_direction(C, thp, php))]
    C2, th2, ph2, thp2, php2, th0, ph0, moved = _recentre(C, th, ph, thp, php, math.cos(th),
                                                          tuple(rest))
    assert moved
    rows = np.reshape(C2, (3, 3))
    assert np.allclose(rows @ rows.T, np.eye(3), atol=1e-12)
    assert np.allclose(_direction(C2, th2, ph2), before[0], atol=1e-12)
    assert np.allclose(_direction(C2, thp2, php2), before[1], atol=1e-12)
    assert np.allclose(_direction(C2, th0, ph0), rest, atol=1e-12)
    assert abs(math.cos(th2)) <= POLE_COS + 1e-12


@pytest.mark.parametrize('seed', range(6))
def test_moments_are_the_virtual_work_of_the_forces(seed):
    """Eq. 4: M_theta = dW/dtheta, M_phi = dW/dphi, W = F_dist . r_centre + F_end . r_end."""
    rng = np.random.default_rng(seed)
    C = random_chart(rng)
    th, ph, seg = 0.3 + 2.5 * rng.random(), 2 * math.pi * rng.random(), 0.02
    fd, fe = rng.normal(size=3), rng.normal(size=3)

    def work(t, p):
        d = np.array(_direction(C, t, p))
        return fd @ (0.5 * seg * d) + fe @ (seg * d)
    eps = 1e-6
    m_theta = (work(th + eps, ph) - work(th - eps, ph)) / (2 * eps)
    m_phi = (work(th, ph + eps) - work(th, ph - eps)) / (2 * eps)
    got = _moments_of_trig(C, math.sin(th), math.cos(th), math.sin(ph), math.cos(ph), seg,
                           tuple(fd), tuple(fe))
    assert got[0] == pytest.approx(m_theta, rel=1e-7, abs=1e-12)
    assert got[1] == pytest.approx(m_phi, rel=1e-7, abs=1e-12)


@pytest.mark.parametrize('integrator', [EXPLICIT, IMPLICIT])
@pytest.mark.parametrize('steps', [10, 100, 1000])
def test_free_oscillation_follows_its_recurrence_in_closed_form(integrator, steps):
    """
    With no moment and no damping x_n = A l1^n + B l2^n, l the characteristic roots.

    explicit (eq. 6): l^2 - (2 - a) l + 1 = 0; implicit: (1 + a W_NEXT) l^2 - (2 - a W_NOW) l
    + (1 + a W_PREV) = 0, a = h^2 k / I. The roots' angle tends to w h, w = sqrt(k / I).
    """
    k, inv_i, h = 2.0, 50.0, 1.0 / 240
    a = h * h * k * inv_i
    if integrator == EXPLICIT:
        coeffs = [1.0, -(2.0 - a), 1.0]
    else:
        coeffs = [1.0 + a * W_NEXT, -(2.0 - a * W_NOW), 1.0 + a * W_PREV]
    l1, l2 = np.roots(coeffs)
    x0, xm1 = 1.0, 0.999                           # x_0 and x_-1
    A, B = np.linalg.solve([[1.0, 1.0], [1.0 / l1, 1.0 / l2]], [x0, xm1])
    x, xp = x0, xm1
    for _ in range(steps):
        x, xp = _next_deviation(x, xp, 0.0, k, inv_i, 0.0, h, integrator), x
    expected = (A * l1 ** steps + B * l2 ** steps).real
    assert x == pytest.approx(expected, abs=1e-10 * steps)
    w = math.sqrt(k * inv_i)
    assert abs(abs(np.angle(l1)) / h - w) / w < a     # consistent with the ODE
    assert abs(l1) <= 1.0 + 1e-12                     # never grows


@pytest.mark.parametrize('integrator', [EXPLICIT, IMPLICIT])
def test_constant_moment_settles_at_its_static_deviation(integrator):
    """With damping the deviation settles at x = M / k (the spring balances the moment)."""
    k, inv_i, h, moment = 2.0, 50.0, 1.0 / 240, 0.3
    x = xp = 0.0
    for _ in range(20000):
        x, xp = _next_deviation(x, xp, moment, k, inv_i, 5.0, h, integrator), x
    assert x == pytest.approx(moment / k, rel=1e-9)


@pytest.mark.parametrize('depth', [1e-4, 3e-3, 2e-2])
@pytest.mark.parametrize('radius', [0.05, 0.1])
def test_guard_turns_the_end_out_of_the_sphere_in_its_plane(depth, radius):
    """The guarded end is GUARD_MARGIN outside, l from the start, in the plane it turned in."""
    centre = np.array([0.0, 0.0, 0.0])
    seg = 0.03
    start = np.array([radius + 0.005, 0.0, 0.0])
    # an end `depth` inside the sphere, reached from the start
    target = radius - depth
    ang = math.acos((start[0] ** 2 + target ** 2 - seg ** 2) / (2 * start[0] * target))
    end = target * np.array([math.cos(ang), math.sin(ang), 0.0])
    assert abs(np.linalg.norm(end - start) - seg) < 1e-12
    spheres = np.array([[*centre, radius]])
    gx, gy, gz, moved = guard_segment(tuple(start), tuple(end), seg, spheres, np.int64(1))
    g = np.array([gx, gy, gz])
    assert moved
    assert np.linalg.norm(g - start) == pytest.approx(seg, abs=1e-12)
    assert np.linalg.norm(g - centre) >= radius + GUARD_MARGIN - 1e-9
    assert abs(g[2]) < 1e-12                      # no sideways turn: the smallest one


@pytest.mark.parametrize('n', [4, 16, 64])
def test_guarded_rest_shape_keeps_lengths_and_leaves_the_sphere(n):
    """A strand drawn straight through a sphere is turned out of it, segment by segment."""
    radius = 0.1
    start = np.array([0.0, 0.02, radius + 0.001])
    s = np.linspace(0.0, 0.25, n + 1)
    rest = (start + s[:, None] * np.array([0.3, 0.0, -1.0]) / math.hypot(0.3, 1.0))[None]
    lengths = np.linalg.norm(np.diff(rest[0], axis=0), axis=1)
    spheres = np.array([[0.0, 0.0, 0.0, radius]])
    shaped = rest.copy()
    guard_rest_shape(shaped, spheres)
    assert np.allclose(np.linalg.norm(np.diff(shaped[0], axis=0), axis=1), lengths, atol=1e-12)
    assert np.linalg.norm(shaped[0, 1:], axis=1).min() >= radius
    assert np.array_equal(shaped[0, 0], rest[0, 0])                  # the root stays


@pytest.mark.parametrize('integrator', ['implicit', 'explicit'])
def test_one_call_step_equals_the_kernels_one_by_one(integrator):
    """
    Check that the one-call step (through CompiledCall) equals the kernels one by one.

    Bit for bit. The run changes parameters (an int damping, then a float one), the wind
    and the style's layout on the way, so the compiled entry point is re-typed whenever a
    type may change.
    """
    from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    sims = [HairSimulator(style, integrator=integrator, damping=8) for _ in range(2)]
    sims[1].solver.fused = False                     # the reference: one kernel at a time
    for _ in _twins_through_stages(sims, style, 0.4, DEFAULT_DT):
        np.testing.assert_array_equal(sims[0].pos, sims[1].pos)
        assert sims[0].counters['contacts'] == sims[1].counters['contacts'] > 0
        assert sims[0].counters['kernel_calls'] < sims[1].counters['kernel_calls']


@pytest.mark.parametrize('integrator', ['implicit', 'explicit'])
def test_one_call_step_equals_the_kernels_one_by_one_at_changing_steps(integrator):
    """
    The same, with steps of 1/60 and 1/90 s in turn under violent motion.

    Eq. 7 bears the hinge's load as the step will take it, with the previous angles moved
    for the new step's length (AnjyoSolver.match_previous_step): the one-call step moves
    them before its forces, the kernels one by one after theirs (contact_hinge then
    hands the reaction the moved ones).
    """
    from hair_sim import HairSimulator, load_hairstyle, paths
    from hair_sim.bench.scenarios import violent
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    sims = [HairSimulator(style, integrator=integrator) for _ in range(2)]
    sims[1].solver.fused = False
    t = 0.0
    for k in range(60):
        dt = 1.0 / 60 if k % 2 else 1.0 / 90
        t += dt
        for sim in sims:
            sim.set_head_pose(t, *violent(t))
            sim.step(dt)
        np.testing.assert_array_equal(sims[0].pos, sims[1].pos)
    assert sims[0].counters['contacts'] == sims[1].counters['contacts'] > 0


def _twins_through_stages(sims, style, seconds, dt):
    """
    Drive sims through violent motion in three stages, yielding after each.

    The second stage adds wind and changes a parameter, the third the style's layout.
    """
    from hair_sim.bench.scenarios import drive, violent
    t = 0.0
    for stage in range(3):
        for sim in sims:
            if stage == 1:
                sim.set_wind([2.0, 1.0, 0.0], turbulence=0.3, seed=4)
                sim.set_params(damping=9.5)
            if stage == 2:
                sim.set_style(style.with_strip_count(60))
            drive(sim, violent, t, seconds, dt)
        t += seconds
        yield stage


def test_one_call_chain_step_equals_the_substeps_one_by_one():
    """
    Check the articulated model's one-call step against its kernels one substep at a time.

    Bit for bit, with the substep counts each takes: a style (inter-strip springs, every
    strand at the finest count) through violent motion, wind, a parameter change and a new
    layout; and the hanging-hair scene in a gusty wind (no springs: strands at their own
    counts, waiting at the others, whose forces are then not worked out).
    """
    from hair_sim import HairSimulator, load_hairstyle, paths
    from hair_sim.bench import hanging
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    sims = [HairSimulator(style, model='articulated') for _ in range(2)]
    sims[1].solver.whole_step = False                # the reference: kernel by kernel
    for _ in _twins_through_stages(sims, style, 0.3, 1.0 / 60.0):
        np.testing.assert_array_equal(sims[0].pos, sims[1].pos)
        for key in ('substeps', 'contacts', 'wall_springs', 'guard_moves'):
            assert sims[0].counters[key] == sims[1].counters[key] > 0
        assert sims[0].counters['kernel_calls'] < sims[1].counters['kernel_calls']
    sims = []
    for whole_step in (True, False):
        sim = HairSimulator.from_strands(hanging.rest_strands(20, 10), hanging.head_model(),
                                         **hanging.scene_params('articulated'))
        sim.solver.whole_step = whole_step
        sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
        sim.set_wind([2.0, 0.5, 0.0], turbulence=0.5, seed=2)   # (each strand's own time)
        for _ in range(30):
            sim.step(1.0 / 60.0)
        sims.append(sim)
    np.testing.assert_array_equal(sims[0].pos, sims[1].pos)
    # multirate did happen: some substeps had strands waiting
    assert sims[0].counters['strand_substeps'] < 20 * sims[0].counters['substeps']
    for key in ('substeps', 'strand_substeps', 'contacts', 'guard_moves'):
        assert sims[0].counters[key] == sims[1].counters[key] > 0


def _winds():
    """Yield wind as callers give it: lists, ints, read-only, Fortran and strided arrays."""
    ro = np.array([1.5, -0.5, 0.2])
    ro.flags.writeable = False
    fortran = np.asfortranarray([[3.0], [1.0], [0.0]])
    strided = np.arange(9.0)[::3] * 0.4
    for v, turbulence, seed in [([2, 1, 0], 0, 0), ((0.5, 2.0, 0.1), 0.3, 4), (ro, 1, 2),
                                (fortran, 0.6, 2 ** 40), (strided, 0.2, 7),
                                (np.float32([4, 0, 0]), np.float64(0.5), np.int8(3)),
                                ([400.0, 0, 0], 0.1, 1), ([0, 0, 0], 0.0, 0)]:
        yield v, turbulence, seed


@pytest.mark.parametrize('model', ['anjyo', 'articulated'])
def test_a_wind_changed_every_step_is_the_wind_the_one_call_step_takes(model):
    """
    Wind set before every step, given every way a caller may: the one-call step keeps up.

    The one-call step is called through its compiled entry point without typing its
    arguments while the simulator's layout holds, and a wind change no longer counts as a
    layout change (it made the next step type every argument again: 0.98 ms for a 0.2 ms
    step of thesis_long). So the wind field must keep its numba type whatever the caller
    gave, and the step must take the new field: bit for bit what the kernels one by one
    (each typed by its dispatcher) make of the same winds, and not the windless hair.
    """
    from numba import typeof
    from hair_sim import HairSimulator, load_hairstyle, paths
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    sims = [HairSimulator(style, model=model) for _ in range(3)]
    if model == 'anjyo':
        sims[1].solver.fused = False
    else:
        sims[1].solver.whole_step = False
    field_type = typeof(sims[0].wind.field)
    dt = 1.0 / 240.0 if model == 'anjyo' else 1.0 / 60.0
    t = 0.0
    for _ in range(3):
        for v, turbulence, seed in _winds():
            t += dt
            for sim in sims[:2]:
                sim.set_wind(v, turbulence, seed)
                assert typeof(sim.wind.field) == field_type
            for sim in sims:
                sim.set_head_pose(t, [0.0, 0.0, 0.0], [0.0, 0.0, np.sin(t), np.cos(t)])
                sim.step(dt)
            np.testing.assert_array_equal(sims[0].pos, sims[1].pos)
    assert np.abs(sims[0].pos - sims[2].pos).max() > 1e-3
    assert sims[0].layout_version == sims[2].layout_version


@pytest.mark.parametrize('style_name', ['thesis_long', 'side_swept_long'])
def test_cached_sines_and_cosines_are_those_of_the_angles(style_name):
    """
    The step carries sin/cos of theta and phi from step to step (sums of angles, no calls).

    After seconds of violent motion, with re-chartings and guard contacts along the way,
    they must still be the sines and cosines of the angles the state holds.
    """
    from hair_sim import HairSimulator, load_hairstyle, paths
    from hair_sim.bench.scenarios import drive, violent
    sim = HairSimulator(load_hairstyle(paths.shipped_style(style_name)).with_strip_count(12))
    drive(sim, violent, 0.0, 3.0, 1.0 / 240)
    assert sim.counters['recharts'] > 0 and sim.counters['guard_moves'] > 0
    sol = sim.solver
    expected = np.stack([np.sin(sol.theta), np.cos(sol.theta), np.sin(sol.phi),
                         np.cos(sol.phi)], axis=-1)
    assert np.abs(sol.trig - expected).max() < 1e-12


@njit(cache=True)
def _atan2_each(y, x, out):
    for k in range(y.shape[0]):
        out[k] = atan2_vectorizable(y[k], x[k])


@pytest.mark.parametrize('seed', range(3))
def test_atan2_vectorizable_is_libm_within_two_ulp(seed):
    """Every quadrant and octant, magnitudes from 1e-300 to 1e300, and the axes' signs."""
    rng = np.random.default_rng(seed)
    n = 200_000
    y = rng.normal(size=n) * 10.0 ** rng.uniform(-300, 300, n)
    x = rng.normal(size=n) * np.where(rng.random(n) < 0.5, 1.0, 10.0 ** rng.uniform(-8, 8, n))
    axes_y = np.array([0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 2.0, -2.0, 1.0, -1.0])
    axes_x = np.array([1.0, 1.0, -1.0, -1.0, 0.0, 0.0, -0.0, -0.0, 1.0, -1.0])
    y, x = np.concatenate([y, axes_y]), np.concatenate([x, axes_x])
    out = np.empty_like(y)
    _atan2_each(y, x, out)
    expected = np.arctan2(y, x)
    assert np.all(np.abs(out - expected) <= 2.0 * np.spacing(np.abs(expected)))
    assert np.array_equal(np.signbit(out), np.signbit(expected))


@njit(cache=True)
def _sin_each(x, out):
    for k in range(x.shape[0]):
        out[k] = sin_vectorizable(x[k])


@pytest.mark.parametrize('magnitude', [1e-300, 1e-8, 1.0, 30.0, 1e4, 1e8])
def test_sin_vectorizable_is_libm_within_a_few_ulp_of_one(magnitude):
    """Both signs, every octant, from 1e-300 up to 1e8 rad (the wind reduces to a few rad)."""
    rng = np.random.default_rng(int(math.log10(magnitude) + 400))
    x = rng.uniform(-magnitude, magnitude, 200_000)
    x = np.concatenate([x, [0.0, -0.0, math.pi / 4, math.pi / 2, math.pi, -math.pi / 2]])
    out = np.empty_like(x)
    _sin_each(x, out)
    expected = np.sin(x)
    # within 2 ulp of 1 (as the reduction's error is, near a zero of sine the argument's
    # own rounding is as large), and exactly x (with its sign) where sin(x) rounds to x
    assert np.max(np.abs(out - expected)) <= 2.0 * np.spacing(1.0)
    tiny = np.abs(x) < 1e-8
    assert np.array_equal(out[tiny], x[tiny])
    assert np.array_equal(np.signbit(out[tiny]), np.signbit(x[tiny]))


@pytest.mark.parametrize('t', [0.0, 1.37, 86_400.0])
def test_the_wind_at_each_strand_is_the_sum_of_its_modes(t):
    """
    The force kernel's wind at each strand's middle is the sum of its modes.

    The kernel reduces the phases and takes a vectorised sine; here the mean plus
    amplitude sin(k . x - w t + phase) of each mode along its direction is evaluated with
    numpy, a day into a run too.
    """
    from hair_sim.physics.forces import _winds_at_middles
    from hair_sim.physics.wind import Wind
    wind = Wind()
    wind.set([3.0, -1.0, 0.5], turbulence=0.7, seed=11)
    rng = np.random.default_rng(3)
    pos = rng.normal(size=(40, 9, 3)) * 0.3
    out = np.zeros((40, 8, 3))
    _winds_at_middles(pos, t, wind.field, out)
    mid = pos[:, 9 // 2]
    arg = mid @ wind.mode_k.T - wind.mode_w * t + wind.mode_phase          # (40, modes)
    expected = wind.velocity + (wind.amplitude * np.sin(arg)) @ wind.mode_dir
    # the argument's rounding: about (w t) * 1e-16 rad
    tol = 1e-14 + wind.amplitude * len(wind.mode_w) * max(1.0, wind.mode_w.max() * t) * 4e-16
    assert np.max(np.abs(out[:, 0] - expected)) <= tol
    assert np.max(np.abs(out[:, 0] - wind.velocity)) > 0.1 * wind.amplitude   # gusts are there


@pytest.mark.parametrize('n_segments', [7, 50, 300])
def test_a_strand_moves_the_same_alone_as_among_others(n_segments):
    """
    Check that the step's blocks of segments (BLOCK, cut anywhere) change nothing.

    Without springs between strips a strand's motion is its own: five strands stepped
    together (their segments cut into blocks across strands, or one strand across blocks
    when it is longer than BLOCK) must move each as it moves alone, bit for bit, through a
    turning head, turbulent wind, head contacts and re-chartings.
    """
    from hair_sim import HairSimulator
    from hair_sim.bench import hanging

    def run(rest):
        sim = HairSimulator.from_strands(rest, hanging.head_model(),
                                         **hanging.scene_params('anjyo'))
        sim.set_wind([1.0, 0.5, 0.0], turbulence=0.5, seed=3)
        for i in range(360):
            yaw = 2.0 * math.sin(i / 15.0)
            sim.set_head_pose(i / 240.0, [0, 0, 0], [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)])
            sim.step(1.0 / 240.0)
        return sim

    rest = hanging.rest_strands(5, n_segments)
    together = run(rest)
    assert (5 * n_segments) % BLOCK != 0 and together.counters['recharts'] > 0
    assert np.abs(together.pos - rest).max() > 0.1
    recharts = 0
    for k in range(5):
        alone = run(rest[k:k + 1])
        np.testing.assert_array_equal(alone.pos[0], together.pos[k])
        recharts += alone.counters['recharts']
    assert recharts == together.counters['recharts']
