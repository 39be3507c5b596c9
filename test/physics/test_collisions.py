"""Collisions with the head model's spheres and the inter-strip springs (thesis ch. 5)."""

import numpy as np
import pytest

from hair_sim import DEFAULT_DT, HairSimulator
from hair_sim.physics import forces
from hair_sim.bench.scenarios import drive, violent
from hair_sim.physics.solvers.anjyo import hold_weights, IMPLICIT


def world_spheres(sim):
    """Return the collision spheres at the head's current pose."""
    R, p = sim.head_pose
    s = sim.spheres_head.copy()
    s[:, :3] = s[:, :3] @ R.T + p
    return s


def penetration_report(sim):
    """Return (deepest vertex, deepest free-standing chord, worst resting chord excess)."""
    pos = sim.strand_positions()
    sph = world_spheres(sim)
    rel = pos[:, :, None, :] - sph[None, None, :, :3]
    depth_v = (sph[None, None, :, 3] - np.linalg.norm(rel, axis=-1)).max()
    a, b = pos[:, :-1, None, :], pos[:, 1:, None, :]
    c = sph[None, None, :, :3]
    d = b - a
    t = np.clip(((c - a) * d).sum(-1) / (d * d).sum(-1), 0.0, 1.0)
    chord = sph[None, None, :, 3] - np.linalg.norm(a + t[..., None] * d - c, axis=-1)
    start_gap = np.linalg.norm(a - c, axis=-1) - sph[None, None, :, 3]
    free = start_gap > forces.CONTACT_SKIN
    seg_len = np.linalg.norm(d, axis=-1)
    sag = seg_len ** 2 / (8 * sph[None, None, :, 3])
    free_depth = np.where(free, chord, -1.0).max()
    resting_excess = np.where(~free, chord - sag, -1.0).max()
    return depth_v, free_depth, resting_excess


@pytest.mark.parametrize('integrator', ['implicit', 'explicit'])
def test_violent_motion_keeps_hair_out_of_the_body(long_style, integrator):
    """3 s of fast nods and shakes: no vertex > 1 mm inside, no segment through a sphere."""
    sim = HairSimulator(long_style, integrator=integrator)
    worst = np.full(3, -1.0)

    def check(s):
        worst[:] = np.maximum(worst, penetration_report(s))

    drive(sim, violent, 0.0, 3.0, DEFAULT_DT, every=check)
    assert sim.counters['guard_moves'] > 0 and sim.counters['contacts'] > 0   # it was tested
    assert worst[0] <= 1e-3, worst
    assert worst[1] <= 1e-3, worst      # segments clear of the skin do not cut through
    assert worst[2] <= 1e-3, worst      # segments resting on a sphere sag at most like a chord


def test_reaction_constraint_removes_inward_force_and_pushes_out():
    """Eqs. 7-10 on one vertex: inward input removed, k * depth outward, damping on V.N."""
    pos = np.array([[[0.0, 0.0, 0.2], [0.0, 0.0, 0.099]]])        # end 1 mm inside
    prev = pos.copy()
    prev[0, 1, 2] += 0.001                                          # moving inwards, 1 mm/step
    length = np.array([[0.101]])
    spheres = np.array([[0.0, 0.0, 0.0, 0.1]])
    f_dist = np.array([[[0.3, 0.0, -1.0]]])                         # pushes in and sideways
    f_end = np.zeros((1, 1, 3))
    strands = forces.Strands(pos=pos, pos_prev=prev, vel=(pos - prev) / 0.01, length=length,
                             mass=np.ones((1, 1)))
    bodies = forces.Bodies(spheres=spheres, sphere_vel=np.zeros((1, 3)),
                           masks=np.array([1], dtype=np.int64))
    contact = np.zeros((1, 1, forces.CONTACT_SLOTS * forces.CONTACT_FIELDS))
    n = forces.reaction_constraint_forces(strands, bodies, 2.0, 0.5, True,
                                          forces.Forces(f_dist=f_dist, f_end=f_end,
                                                        contact=contact))
    assert n == 1
    np.testing.assert_allclose(f_dist[0, 0], [0.3, 0.0, 0.0])      # eq. 7: tangential kept
    k, c = 2.0 * 0.101, 0.5 * 0.101
    np.testing.assert_allclose(f_end[0, 0], [0.0, 0.0, k * 0.001 + c * 0.1])   # eq. 8


def wall_penetration(sim):
    """Sum over neighbour pairs of how far vertices are past their neighbour's wall."""
    pos = sim.strand_positions()
    sph = world_spheres(sim)[:sim.n_scalp]
    total = 0.0
    for q, (a, b) in enumerate(sim.pairs):
        for j in range(1, pos.shape[1]):
            for side, (me, other) in enumerate(((a, b), (b, a))):
                sd, _, _, _, along = forces.wall_signed_distance(pos, sph, me, other, j)
                if 0.0 <= along <= 1.0:             # beside the wall, not past its ends
                    total += max(0.0, -sd * sim.wall_sign[q, j, side])
    return total


def test_inter_strip_springs_reduce_wall_penetration(long_style):
    """
    Inter-strip handling on (thesis fig. 5.1b) lets strips cross walls less than off (5.1c).

    Same scripted motion and wind; the measure sums how far vertices get past their
    neighbour's projected wall.
    """
    results = {}
    for on in (True, False):
        sim = HairSimulator(long_style, inter_strip=on)
        sim.set_wind([0.0, 6.0, 0.0], turbulence=0.5, seed=5)
        acc = [0.0]

        def measure(s):
            acc[0] += wall_penetration(s)

        assert wall_penetration(sim) == 0.0          # at rest every strip is on its side
        drive(sim, violent, 0.0, 1.5, DEFAULT_DT, every=measure)
        results[on] = acc[0]
    assert results[False] > 0.0
    assert results[True] < 0.7 * results[False], results


@pytest.mark.parametrize('margin', [1e-6, forces.GUARD_MARGIN])
def test_guard_puts_the_end_out_when_two_spheres_pull_against_each_other(margin):
    """
    A long tip segment with its end in one scalp sphere and its chord dipping into another.

    Taken from the articulated model's gale (thesis_long, 1/240 s, t = 1.254 s): pushing the
    end out of sphere 1 dipped the chord into sphere 4 and lifting the chord pushed the end
    back in; after the sweeps ran out the tip was 3.3 um inside sphere 1. The end must
    come out of every sphere, the segment keep its length, and the chord dip no deeper than
    the guard's allowance.
    """
    start = np.array([-0.00918315745226566, 0.04302525658271666, -0.06286480074315245])
    end = np.array([-0.03590961562861224, 0.00692191057125079, -0.03810259159956156])
    seg = 0.05129251564845079
    spheres = np.array([
        [0.03714748937857184, -0.01260965086141392, 0.01024844809648068, 0.075],
        [0.00609560117439985, 0.00854988033429361, 0.02396174378108854, 0.075],
        [0.02991536202702248, -0.01496229058501381, -0.04625076800694779, 0.062],
        [0.01230545023559999, -0.00825757865843007, -0.08188695529851764, 0.045],
        [-0.03075881051373536, 0.01645425174850773, -0.1008552152095374, 0.05],
        [-0.05135144916258685, 0.0225439075391882, -0.15688073908775615, 0.056]])
    assert (np.linalg.norm(end - spheres[:, :3], axis=1) - spheres[:, 3]).min() < 0.0
    x, y, z, moved = forces.guard_segment(tuple(start), tuple(end), seg, spheres,
                                          np.int64(63), margin)
    out = np.array([x, y, z])
    assert moved
    clearance = np.linalg.norm(out - spheres[:, :3], axis=1) - spheres[:, 3]
    assert clearance.min() > 0.0, clearance.min()
    assert abs(np.linalg.norm(out - start) - seg) < 1e-12
    chord = start + np.linspace(0.0, 1.0, 2001)[:, None] * (out - start)
    dip = -(np.linalg.norm(chord[:, None] - spheres[None, :, :3], axis=2) - spheres[:, 3]).min()
    assert dip <= forces.SEGMENT_TOLERANCE + 1e-6, dip


@pytest.mark.parametrize('margin', [forces.GUARD_MARGIN, 1e-6])
def test_guard_puts_an_end_caught_in_a_crease_out_of_both_spheres(margin):
    """
    A tip segment whose end is caught in the crease between two spheres (neck and body).

    Taken from the articulated model's long random run (thesis_long, 1/240 s, step 85440):
    turning the end out of one sphere put it into the other, and after the sweeps ran out
    the tip was 0.28 mm inside. The end must come out of both, on the nearest point of the
    crease (checked by brute force over directions), and the segment keep its length.
    """
    start = np.array([-0.08442225761005523, -0.08251336667460477, -0.0429870161377269])
    end = np.array([-0.03245112796146634, -0.07688929480344667, -0.04639247583538321])
    seg = 0.05238535727772359
    spheres = np.array([
        [0.010286867834338409, -0.06327414620370984, -0.004774161359513387, 0.062],
        [-0.0064525935982482595, -0.07907138555408694, -0.08915566205637135, 0.05]])
    assert (np.linalg.norm(end - spheres[:, :3], axis=1) - spheres[:, 3]).min() < 0.0
    x, y, z, moved = forces.guard_segment(tuple(start), tuple(end), seg, spheres,
                                          np.int64(3), margin)
    out = np.array([x, y, z])
    assert moved
    clearance = np.linalg.norm(out - spheres[:, :3], axis=1) - spheres[:, 3]
    assert clearance.min() > 0.0, clearance
    assert abs(np.linalg.norm(out - start) - seg) < 1e-12
    # the nearest allowed end, by brute force over a fine grid of directions near the end
    rng = np.random.default_rng(0)
    d0 = (end - start) / seg
    dirs = d0 + rng.normal(scale=0.05, size=(400000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ends = start + seg * dirs
    gap = np.linalg.norm(ends[:, None] - spheres[None, :, :3], axis=2) - spheres[:, 3]
    allowed = ends[(gap >= margin).all(axis=1)]
    nearest = np.linalg.norm(allowed - end, axis=1).min()
    assert np.linalg.norm(out - end) <= nearest + 1e-5, (np.linalg.norm(out - end), nearest)


def _crease_head(tangent_points, normal, radius):
    """Return a head of spheres touching a line at tangent_points from below (-normal)."""
    from hair_sim.modeling.head import HeadModel
    centres = np.asarray(tangent_points) - (radius + 2e-4) * np.asarray(normal)
    scalp = np.hstack([centres, np.full((len(centres), 1), radius)])
    return HeadModel(name='crease', frame_id='head', scalp=scalp, body=np.zeros((0, 4)),
                     projection_sphere=np.array([0.0, 0.0, 0.1, 0.001]),
                     hairline={'front_x': 1.0, 'front_z': -1.0, 'back_x': -1.0, 'back_z': -1.0})


def test_every_contact_of_a_segment_is_recorded_for_the_implicit_solve():
    """End on one sphere, chord on another: both contacts, with their normals and levers."""
    start = np.array([0.0, 0.0, 0.1])
    end = start + [0.04, 0.0, 0.0]
    head = _crease_head([end, 0.5 * (start + end)], [0.0, 0.0, 1.0], 0.008)
    pos = np.array([[start, end]])
    strands = forces.Strands(pos=pos, pos_prev=pos.copy(), vel=np.zeros_like(pos),
                             length=np.array([[0.04]]), mass=np.ones((1, 1)))
    bodies = forces.Bodies(spheres=head.scalp, sphere_vel=np.zeros((2, 3)),
                           masks=np.array([3], dtype=np.int64))
    contact = np.zeros((1, 1, forces.CONTACT_SLOTS * forces.CONTACT_FIELDS))
    n = forces.reaction_constraint_forces(strands, bodies, 2.0, 0.5, True,
                                          forces.Forces(f_dist=np.zeros((1, 1, 3)),
                                                        f_end=np.zeros((1, 1, 3)),
                                                        contact=contact))
    assert n == 2
    slots = contact.reshape(forces.CONTACT_SLOTS, forces.CONTACT_FIELDS)
    held = slots[slots[:, forces.CONTACT_C] > 0.0]
    assert len(held) == 2
    np.testing.assert_allclose(sorted(held[:, forces.CONTACT_LEVER]), [0.5, 1.0], atol=1e-9)
    np.testing.assert_allclose(held[:, forces.CONTACT_NX:forces.CONTACT_NZ + 1],
                               [[0.0, 0.0, 1.0]] * 2, atol=1e-9)


@pytest.mark.parametrize('lever', [0.3, 0.5, 0.8])
def test_a_chord_contact_acts_on_the_chain_as_the_force_at_its_point(lever):
    """
    Eq. 10's response at Q, for a model whose segments pass forces on to their parents.

    The thesis model moves it to the free end with weight t (the same moment about the
    segment's start, all that its segments feel); the chain gets the force at Q itself:
    the same total force and the same moment about the start, split between the
    segment's centre and its end (the wrench of a point force on a rigid rod).
    """
    start = np.array([0.0, 0.0, 0.1])
    end = start + [0.04, 0.0, 0.0]
    q = start + lever * (end - start)
    head = _crease_head([q], [0.0, 0.0, 1.0], 0.008)
    pos = np.array([[start, end]])
    strands = forces.Strands(pos=pos, pos_prev=pos.copy(), vel=np.full_like(pos, -0.2),
                             length=np.array([[0.04]]), mass=np.ones((1, 1)))
    bodies = forces.Bodies(spheres=head.scalp, sphere_vel=np.zeros((1, 3)),
                           masks=np.array([1], dtype=np.int64))
    out = {}
    for at_q in (False, True):
        f_dist, f_end = np.zeros((1, 1, 3)), np.zeros((1, 1, 3))
        contact = np.zeros((1, 1, forces.CONTACT_SLOTS * forces.CONTACT_FIELDS))
        n = forces.reaction_constraint_forces(strands, bodies, 2.0, 0.5, True,
                                              forces.Forces(f_dist=f_dist, f_end=f_end,
                                                            contact=contact),
                                              None, None, False, at_q)
        assert n == 1
        tt = contact[0, 0, forces.CONTACT_LEVER]
        out[at_q] = (f_dist[0, 0], f_end[0, 0], tt)
    np.testing.assert_allclose(out[False][2], lever, atol=1e-9)
    assert np.array_equal(out[False][0], np.zeros(3))
    force_at_q = out[False][1] / lever                  # the thesis' t F at the end
    assert force_at_q[2] > 0.0                          # (it pushes out: the rod falls in)
    f_dist, f_end, _ = out[True]
    np.testing.assert_allclose(f_dist + f_end, force_at_q, rtol=1e-12)
    arm = end - start
    np.testing.assert_allclose(np.cross(0.5 * arm, f_dist) + np.cross(arm, f_end),
                               np.cross(lever * arm, force_at_q), rtol=1e-12, atol=1e-18)


def test_without_a_record_the_forces_are_the_same_and_the_record_is_left_alone():
    """
    A model that does not read the contact record (the thesis model) skips writing it.

    Vertex and chord contacts on two spheres: the forces and the count are those of the
    recording call, and the record, filled with a sentinel, is not touched.
    """
    start = np.array([0.0, 0.0, 0.1])
    end = start + [0.04, 0.0, 0.0]
    head = _crease_head([end, 0.5 * (start + end)], [0.0, 0.0, 1.0], 0.008)
    pos = np.array([[start, end - [0.0, 0.0, 5e-4]]])           # the end a little inside
    strands = forces.Strands(pos=pos, pos_prev=pos.copy(), vel=np.full_like(pos, 0.1),
                             length=np.array([[0.04]]), mass=np.ones((1, 1)))
    bodies = forces.Bodies(spheres=head.scalp, sphere_vel=np.zeros((2, 3)),
                           masks=np.array([3], dtype=np.int64))
    out = {}
    for record in (True, False):
        f_dist = np.array([[[0.2, 0.1, -1.0]]])
        f_end = np.array([[[0.0, 0.3, -0.5]]])
        contact = np.full((1, 1, forces.CONTACT_SLOTS * forces.CONTACT_FIELDS), 7.0)
        n = forces.reaction_constraint_forces(strands, bodies, 2.0, 0.5, record,
                                              forces.Forces(f_dist=f_dist, f_end=f_end,
                                                            contact=contact))
        out[record] = (n, f_dist, f_end, contact)
    assert out[True][0] == out[False][0] == 2
    np.testing.assert_array_equal(out[True][1], out[False][1])
    np.testing.assert_array_equal(out[True][2], out[False][2])
    assert (out[True][3] != 7.0).any()              # the recording call wrote its record
    assert (out[False][3] == 7.0).all()


@pytest.mark.parametrize('radius', [0.005, 0.008, 0.012])
def test_a_segment_falling_into_a_crease_takes_no_energy_from_its_contacts(radius):
    """
    A rod hinged at its start falls onto two spheres at once: end on one, chord on the other.

    Articulated model, no joint damping. Contacts take energy or keep it; with
    only one of the two folded into the implicit solve, the other's damping acted
    explicitly (h c / m above 2) and the energy rose by 0.55 % of the fall's peak kinetic
    energy in one step (1/240 s); the bound is 0.1 %.
    """
    from hair_sim.physics.simulator import HairSimulator as Sim
    beta, length, dt = 0.1, 0.04, 1.0 / 240.0
    start = np.array([0.0, 0.0, 0.1])
    along = np.array([np.cos(beta), 0.0, -np.sin(beta)])
    up = np.array([np.sin(beta), 0.0, np.cos(beta)])
    head = _crease_head([start + length * along, start + 0.5 * length * along], up, radius)
    rod = np.array([[start, start + [length, 0.0, 0.0]]])       # level: it falls by beta
    sim = Sim.from_strands(rod, head, model='articulated', inter_strip=False,
                           gravity_compensation=False, sleep_tolerance=0.0,
                           drag_coefficient=0.0, air_damping=0.0, damping=0.0,
                           stiffness_scale=0.05, root_stiffness_scale=0.01)
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    energy = [sum(sim.energy())]
    peak = 0.0
    for _ in range(int(0.5 / dt)):
        sim.step(dt)
        energy.append(sum(sim.energy()))
        peak = max(peak, sim.kinetic_energy())
    assert sim.counters['contacts'] > 0
    rise = np.diff(energy).max()
    assert rise < 1e-3 * peak, (rise, peak)


def _horizontal_segment_on_a_sphere(alpha, k, length=0.05):
    """
    One segment along +x whose end rests on top of a sphere (r = 0.1 at the origin).

    Its hinge (eq. 3), k, has its rest turned up by alpha: the spring lifts the end with
    a force k alpha / l (the segment lies on its chart's equator, phi = 0, with e_phi
    straight up, so the moment -k (phi - alpha) is that of an upward force at the end).
    Returns (strands, bodies, hinge).
    """
    end = np.array([0.0, 0.0, 0.1])
    pos = np.array([[end - [length, 0.0, 0.0], end]])
    strands = forces.Strands(pos=pos, pos_prev=pos.copy(), vel=np.zeros_like(pos),
                             length=np.array([[length]]), mass=np.ones((1, 1)))
    bodies = forces.Bodies(spheres=np.array([[0.0, 0.0, 0.0, 0.1]]),
                           sphere_vel=np.zeros((1, 3)), masks=np.array([1], dtype=np.int64))
    chart = np.array([[[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]]])  # x, y, pole
    theta, phi = np.full((1, 1), np.pi / 2), np.zeros((1, 1))
    trig = np.array([[[1.0, 0.0, 0.0, 1.0]]])            # sin, cos of theta; of phi
    rest = np.array([[[np.cos(alpha), 0.0, np.sin(alpha)]]])
    hinge = (chart, theta, phi, trig, rest, np.full((1, 1), k), np.eye(3), theta.copy(),
             phi.copy(), np.ones((1, 1)), hold_weights(IMPLICIT, 12.0, 1.0 / 60))  # at rest
    return strands, bodies, hinge


def _react_with_hinge(strands, bodies, input_forces, hinge):
    """Apply eqs. 7-10 (k = 2, no damping, no record) with the hinge; return the contacts."""
    f_dist, f_end = input_forces
    return forces.reaction_constraint_forces(strands, bodies, 2.0, 0.0, False,
                                             forces.Forces(f_dist=f_dist, f_end=f_end,
                                                           contact=np.zeros((1, 1, 1))),
                                             hinge)


@pytest.mark.parametrize('lift_over_weight', [0.25, 0.5, 0.9, 1.1, 2.0])
def test_the_surface_bears_what_the_forces_and_the_hinge_press_on_it_and_no_more(
        lift_over_weight):
    """
    Eq. 7 with the thesis model's hinge spring counted: a segment resting on a sphere.

    Its weight presses its end on the surface (w = 1: the end is on it), and its hinge
    spring lifts it by a force of lift_over_weight times that. While the weight wins, the
    surface bears the difference (in moments about the start: nothing left along the
    normal); when the spring wins, the surface bears nothing and the forces are kept.
    Without the hinge, eq. 7 removed the whole weight and the spring threw the end off.
    """
    weight = 0.02                        # N, end-equivalent: half the distributed force
    length, k = 0.05, 1e-2
    alpha = lift_over_weight * weight * length / k         # 0.025 to 0.2 rad
    strands, bodies, hinge = _horizontal_segment_on_a_sphere(alpha, k, length)
    lift = k * alpha / length
    f_dist = np.array([[[0.003, 0.0, -2.0 * weight]]])             # gravity and a side push
    f_end = np.zeros((1, 1, 3))
    n = _react_with_hinge(strands, bodies, (f_dist, f_end), hinge)
    assert n == 1
    pressing = 0.5 * f_dist[0, 0] + f_end[0, 0]            # as moments about the start
    assert pressing[0] == pytest.approx(0.5 * 0.003, abs=1e-15)          # along: kept
    net_normal = pressing[2] + lift
    assert net_normal == pytest.approx(max(0.0, lift - weight), abs=1e-12)
    # the spring's force at the end has the moments of eq. 3 (independent of the above)
    s = forces.hinge_end_force(0, 0, strands.length, hinge)
    np.testing.assert_allclose(s, [0.0, 0.0, lift], atol=1e-15)


@pytest.mark.parametrize('seed', range(6))
def test_the_hinge_end_force_has_the_moments_of_eq_3(seed):
    """Its moments by eq. 4 are -k times the deviations from the rest angles, any chart."""
    from hair_sim.physics.solvers.anjyo import _moments_of_trig
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    chart = q.T[None, None]                              # rows x, y and the polar axis
    theta = rng.uniform(np.pi / 4, 3 * np.pi / 4)        # where the model keeps segments
    phi = rng.uniform(-np.pi, np.pi)
    rest_world = rng.normal(size=3)
    rest_world /= np.linalg.norm(rest_world)
    k, length = rng.uniform(1e-5, 1e-3), rng.uniform(0.01, 0.05)
    hinge = (chart, np.full((1, 1), theta), np.full((1, 1), phi),
             np.array([[[np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)]]]),
             (R.T @ rest_world)[None, None], np.full((1, 1), k), R, np.full((1, 1), theta),
             np.full((1, 1), phi), np.ones((1, 1)), hold_weights(IMPLICIT, 12.0, 1.0 / 60))
    f = forces.hinge_end_force(0, 0, np.full((1, 1), length), hinge)
    C = tuple(chart[0, 0].ravel())
    m_th, m_ph = _moments_of_trig(C, np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi),
                                  length, (0.0, 0.0, 0.0), f)
    in_chart = chart[0, 0] @ rest_world
    x_th = theta - np.arccos(in_chart[2])
    x_ph = (phi - np.arctan2(in_chart[1], in_chart[0]) + np.pi) % (2 * np.pi) - np.pi
    assert m_th == pytest.approx(-k * x_th, rel=1e-9, abs=1e-15)
    assert m_ph == pytest.approx(-k * x_ph, rel=1e-9, abs=1e-15)


@pytest.mark.parametrize('integrator', ['explicit', 'implicit'])
@pytest.mark.parametrize('seed', range(4))
def test_the_hinge_end_force_is_what_holds_a_moving_segment_where_it_is(seed, integrator):
    """
    Taken against its moments by eq. 4, the thesis model's update leaves the segment put.

    The load eq. 7 may bear of the hinge is what the update of eqs. 1-6 needs from outside
    to keep the angles where they are: its spring as the update takes it and the motion
    the last step carries in. Checked against _next_deviation itself, for a segment
    moving (theta_prev, phi_prev away from theta, phi), any chart, stiffness and step;
    at rest it is eq. 3's -k x (the test above). With eq. 3's -k x as the load, right
    after the guard stopped a stiff segment (its previous angles past its rest angles),
    the surface threw it off by 1.5 times its deviation.
    """
    from hair_sim.physics.solvers import anjyo
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    chart = q.T[None, None]
    theta = rng.uniform(np.pi / 4, 3 * np.pi / 4)
    phi = rng.uniform(-np.pi, np.pi)
    theta_prev, phi_prev = theta + rng.normal(0.0, 0.1), phi + rng.normal(0.0, 0.1)
    rest_world = rng.normal(size=3)
    rest_world /= np.linalg.norm(rest_world)
    k, length = 10 ** rng.uniform(-6, -3), rng.uniform(0.01, 0.05)
    inv_i = 3.0 / (2.5e-3 * length ** 3)               # a rod of 2.5 g/m about its end
    damping, h = rng.uniform(0.0, 20.0), rng.choice([1 / 60, 1 / 240])
    method = anjyo.EXPLICIT if integrator == 'explicit' else anjyo.IMPLICIT
    hinge = (chart, np.full((1, 1), theta), np.full((1, 1), phi),
             np.array([[[np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)]]]),
             rest_world[None, None], np.full((1, 1), k), np.eye(3),
             np.full((1, 1), theta_prev), np.full((1, 1), phi_prev), np.full((1, 1), inv_i),
             hold_weights(method, damping, h))
    f = forces.hinge_end_force(0, 0, np.full((1, 1), length), hinge)
    C = tuple(chart[0, 0].ravel())
    m_th, m_ph = anjyo._moments_of_trig(C, np.sin(theta), np.cos(theta), np.sin(phi),
                                        np.cos(phi), length, (0.0, 0.0, 0.0), f)
    in_chart = chart[0, 0] @ rest_world
    x_th = theta - np.arccos(in_chart[2])
    x_ph = (phi - np.arctan2(in_chart[1], in_chart[0]) + np.pi) % (2 * np.pi) - np.pi
    for x, xp, m in ((x_th, x_th - (theta - theta_prev), m_th),
                     (x_ph, x_ph - (phi - phi_prev), m_ph)):
        held = anjyo._next_deviation(x, xp, -m, k, inv_i, damping, h, method)
        assert held == pytest.approx(x, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize('lift_over_weight', [0.25, 0.5, 0.9, 1.1, 1.5, 2.0, 2.5])
def test_a_chord_on_a_sphere_bears_what_the_forces_and_the_hinge_press_on_it(
        lift_over_weight):
    """
    Eq. 10, the same: a segment across the top of a sphere, touching it at its middle Q.

    Its ends are clear of the sphere. Eq. 10's input force at Q, interpolated from the
    ends, is its weight W (half of the segment's 2 W; the start's share is none: no
    segment before it). The segment turns about its start (eq. 4): its weight's moment is
    2 W l / 2, the hinge lifts with k alpha, and Q's lever is l / 2, so Q is pressed with
    at most (W l - k alpha) / (l / 2) = 2 W - lift_at_q. The surface bears the lesser,
    and nothing when the spring wins.
    """
    weight, length, k = 0.02, 0.1, 1e-2
    lift_at_q = lift_over_weight * weight
    alpha = 0.5 * lift_at_q * length / k
    strands, bodies, hinge = _horizontal_segment_on_a_sphere(alpha, k, length)
    pos = strands.pos
    pos[0, :, 0] += 0.5 * length                 # across the top: x from -l/2 to l/2
    assert np.linalg.norm(pos[0, 1]) > 0.1 + forces.CONTACT_SKIN     # the end is clear
    f_dist = np.array([[[0.0, 0.0, -2.0 * weight]]])
    f_end = np.zeros((1, 1, 3))
    n = _react_with_hinge(strands, bodies, (f_dist, f_end), hinge)
    assert n == 1
    borne = f_end[0, 0, 2] / 0.5                  # applied at Q, moved to the end by tt
    pressing_q = (2.0 * weight * length / 2 - k * alpha) / (length / 2)
    assert borne == pytest.approx(min(weight, max(0.0, pressing_q)), abs=1e-12)
    np.testing.assert_array_equal(f_end[0, 0, :2], [0.0, 0.0])


@pytest.mark.parametrize('push_on_start', [0.0, 0.01, 0.05, 0.2])
def test_a_chord_bears_nothing_of_the_segment_before_it(push_on_start):
    """
    Eq. 10 on the second segment of a strand: the force on its start turns the first one.

    Two 5 cm segments along x, the second across the top of a sphere (touching it at its
    middle Q), no hinge springs, only the second's weight W. The first segment's end (the
    second's start) is pushed down by push_on_start. In the thesis model a segment turns
    about its start under its own loads only (eq. 4), so what presses the second on Q is
    its weight's moment over Q's lever, 2 W l / 2 / (l / 2) = 2 W, capped by eq. 10's
    interpolated force (W, plus half the push). Bearing the push as well left the second
    segment's moments pointing away from the sphere, and it was thrown off and fell back
    every step (side_swept_long's tips at 1/60 s, 3-12 mm a step for ever).
    """
    weight, length = 0.02, 0.05
    x = np.array([-1.5, -0.5, 0.5]) * length
    pos = np.stack([x, np.zeros(3), np.full(3, 0.1)], axis=1)[None]
    strands = forces.Strands(pos=pos, pos_prev=pos.copy(), vel=np.zeros_like(pos),
                             length=np.full((1, 2), length), mass=np.ones((1, 2)))
    bodies = forces.Bodies(spheres=np.array([[0.0, 0.0, 0.0, 0.1]]),
                           sphere_vel=np.zeros((1, 3)), masks=np.array([1], dtype=np.int64))
    chart = np.tile(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]), (1, 2, 1, 1))
    theta, phi = np.full((1, 2), np.pi / 2), np.zeros((1, 2))
    trig = np.tile([1.0, 0.0, 0.0, 1.0], (1, 2, 1))
    rest = np.tile([1.0, 0.0, 0.0], (1, 2, 1))
    hinge = (chart, theta, phi, trig, rest, np.zeros((1, 2)), np.eye(3), theta.copy(),
             phi.copy(), np.ones((1, 2)), hold_weights(IMPLICIT, 12.0, 1.0 / 60))
    f_dist = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, -2.0 * weight]]])
    f_end = np.array([[[0.0, 0.0, -push_on_start], [0.0, 0.0, 0.0]]])
    assert _react_with_hinge(strands, bodies, (f_dist, f_end), hinge) >= 1
    borne = f_end[0, 1, 2] / 0.5                  # applied at Q, moved to the end by tt
    interpolated = 0.5 * push_on_start + weight
    assert borne == pytest.approx(min(interpolated, 2.0 * weight), abs=1e-12)
    # what is left of the second segment's own loads still presses it on the sphere
    assert 0.5 * f_dist[0, 1, 2] + f_end[0, 1, 2] <= 1e-15
