"""
hair_sim_bench fall: the strands the stress bench's 30 m/s gale leaves moving, in MuJoCo too.

`hair_sim_bench stress --model articulated` fails its 30 m/s gale at 1/240 and 1/1000 s on
one count only: the hair is not asleep 4 s after the wind stops (head held still). Strands
rooted at the crown, blown over it, lie on the frictionless head spheres near a balance
that is unstable, and slide off seconds later. This command asks whether that is the
chain's physics or hair_sim's integrator and contacts, by running the same strands from
the same state in MuJoCo.

For each of those steps: the stress case is driven as `stress.run_case` drives it (the
thesis_long style, violent head motion, the gale with full turbulence, seed 1, 2 s), the
wind is stopped and the head held still. The springs between strands (thesis 5.2) are
switched off at the stop, so that every strand moves on its own; hair_sim then runs on
(both with them, as the stress case does, and without). The strands whose tips still move
faster than the sleep tolerance (sleep_tolerance over sleep_delay) in the window's last
second (3-4 s after the stop) are the late ones (at most MAX_STRANDS, the fastest). From
hair_sim's state START_S after the stop (the head's own motion has died out), MuJoCo runs
those strands:

- one body per segment with its mass at its centre and a rod's inertia, ball joints at
  the vertices with the joints' dampers (MuJoCo's implicitfast integrator), the first
  joint on a body fixed at the root in the head's frame;
- the bending springs as couples on the rods, the gradient of the Hencky bar-chain's
  energy as the solver defines it (each joint's bend from its rest under the parent's
  twist-free frame, with the sag-free preload; `chain_energy` below, written from that
  definition, not from the solver's kernels, and checked against the solver's
  potential_energy by the suite);
- drag against still air, -nu m v at every segment's centre, each step;
- the head's spheres as frictionless (condim 1) contacts with capsules of CAPSULE_RADIUS,
  the spheres shrunk by it; hair_sim's contacts act at the vertices instead, so a chord
  may cut up to a couple of mm into a sphere where MuJoCo's capsule cannot;
- the hair_sim state copied in: rotations (the joint's relative rotation) and angular
  velocities.

Each run gives, from the stop, the last time a late strand's tip moved faster than the
sleep tolerance (the plot shows the fastest tip), and where the tips end. MuJoCo is a
benchmark-only dependency (requirements.txt; make setup installs it); without it the
command says so and exits 1.
"""

import copy
import math

from numba import njit
import numpy as np

from hair_sim import load_hairstyle, paths
from hair_sim.bench.common import progress, save_figure
from hair_sim.bench.hanging import apply_air_damping, chain_tips
from hair_sim.bench.scenarios import violent
from hair_sim.bench.stress import GALE
from hair_sim.physics.simulator import HairSimulator

STYLE = 'thesis_long'
GALE_S = 2.0                 # as the stress case
WINDOW_S = 4.0               # the stress case's sleep window
START_S = 0.5                # MuJoCo starts this long after the stop
AFTER_S = 12.0               # how long after the stop the runs go on
SAMPLE_S = 0.05              # the tips are sampled this often
MUJOCO_DT = 1.0 / 4000.0
CAPSULE_RADIUS = 2e-4
MAX_STRANDS = 8              # MuJoCo runs at most this many of the late strands


@njit(cache=True)
def chain_energy(axes, R_head, rest_rel, offset, k):
    """
    Return the bending springs' energy (J) of one strand whose rods point along axes.

    axes (n, 3): each rod's unit direction in the world; rest_rel (n, 3, 3): each joint's
    rest, the child's frame in its parent's; offset (n, 3) the sag-free preload e0, k (n,)
    the joints' stiffness. A joint's frame is its rest frame under the parent's, A = F
    rest_rel, turned by the minimal rotation taking A's z to the rod (twist-free); with v
    the rod in A's frame, theta its angle from z and n the unit z x v, the joint holds
    k (theta^2 - 2 sigma theta n.e0 + |e0|^2) / 2, sigma 1 up to a right angle and
    sin(theta) beyond.
    """
    F = R_head.copy()
    total = 0.0
    for i in range(axes.shape[0]):
        A = F @ rest_rel[i]
        v = A.T @ axes[i]
        v = v / math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        st = math.sqrt(v[0] * v[0] + v[1] * v[1])
        theta = math.atan2(st, v[2])
        n_e0 = (-v[1] * offset[i, 0] + v[0] * offset[i, 1]) / st if st > 1e-12 else 0.0
        sigma = 1.0 if theta <= 0.5 * math.pi else st
        e0_2 = offset[i, 0] ** 2 + offset[i, 1] ** 2 + offset[i, 2] ** 2
        total += 0.5 * k[i] * (theta * theta - 2.0 * sigma * theta * n_e0 + e0_2)
        c = 1.0 + v[2]
        if c > 1e-9:
            M = np.array([[1.0 - v[0] * v[0] / c, -v[0] * v[1] / c, v[0]],
                          [-v[0] * v[1] / c, 1.0 - v[1] * v[1] / c, v[1]],
                          [-v[0], -v[1], v[2]]])
            F = A @ M
        else:                       # bent back on its rest axis: the frame is kept
            F = A
    return total


@njit(cache=True)
def chain_spring_couples(axes, R_head, rest_rel, offset, k, out):
    """
    Write into out (n, 3) the couple (N m, world) the springs put on each rod.

    Turning rod i by a small world rotation phi moves its axis by phi x u, so the couple is
    -u x dE/du (central differences of chain_energy across the rod).
    """
    eps = 1e-7
    for i in range(axes.shape[0]):
        u = axes[i].copy()
        a = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(u, a)
        t1 /= math.sqrt((t1 * t1).sum())
        t2 = np.cross(u, t1)
        grad = np.zeros(3)
        for t in (t1, t2):
            plus = axes.copy()
            plus[i] = u + eps * t
            minus = axes.copy()
            minus[i] = u - eps * t
            grad += t * (chain_energy(plus, R_head, rest_rel, offset, k)
                         - chain_energy(minus, R_head, rest_rel, offset, k)) / (2.0 * eps)
        out[i] = -np.cross(u, grad)


def _quat(R):
    """Return MuJoCo's quaternion (w, x, y, z) of the rotation matrix R."""
    import mujoco
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def mujoco_chains(state, spheres):
    """
    Return (model, data, segment body ids (n_strands, n_seg)) of the strands in state.

    state: the dict of strand_state; spheres (m, 4): world centres and radii.
    """
    import mujoco
    length, mass, d = state['length'], state['mass'], state['d']
    n_s, n_seg = length.shape
    out = ['<mujoco><option timestep="%.17g" gravity="0 0 %.17g" integrator="implicitfast"/>'
           % (MUJOCO_DT, -state['gravity']),
           '<default><geom contype="1" conaffinity="0" condim="1" margin="0" '
           'solref="0.002 1"/></default><worldbody>']
    for s in spheres:
        out.append('<geom type="sphere" pos="%.17g %.17g %.17g" size="%.17g" contype="0" '
                   'conaffinity="1"/>' % (s[0], s[1], s[2], s[3] - CAPSULE_RADIUS))
    for a in range(n_s):
        inner = ['<body pos="%.17g %.17g %.17g" quat="%.17g %.17g %.17g %.17g">'
                 % (*state['pos'][a, 0], *_quat(state['R_head']))]
        for i in range(n_seg):
            ln, m = length[a, i], mass[a, i]
            perp = m * ln * ln / 12.0
            # the twist carries no spring here (the energy is the axes' alone): any axial
            # inertia will do; the rod's own (~1e-11) would only make MuJoCo's step stiff
            axial = max(state['inertia_axial'][a, i], 0.1 * perp)
            inner.append('<body pos="0 0 %.17g"><joint type="ball" damping="%.17g"/>'
                         '<inertial pos="0 0 %.17g" mass="%.17g" diaginertia="%.17g %.17g %.17g"/>'
                         '<geom type="capsule" fromto="0 0 0 0 0 %.17g" size="%.17g" mass="0"/>'
                         % (0.0 if i == 0 else length[a, i - 1], d[a, i], ln / 2, m, perp, perp,
                            axial, ln, CAPSULE_RADIUS))
        out.append(''.join(inner) + '</body>' * (n_seg + 1))
    out.append('</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string('\n'.join(out))
    data = mujoco.MjData(model)
    bodies = np.array([[1 + a * (n_seg + 1) + 1 + i for i in range(n_seg)]
                       for a in range(n_s)])
    R, omega = state['R'], state['omega']
    for a in range(n_s):
        for i in range(n_seg):
            joint = a * n_seg + i
            parent_R = state['R_head'] if i == 0 else R[a, i - 1]
            parent_w = np.zeros(3) if i == 0 else omega[a, i - 1]
            qa, va = model.jnt_qposadr[joint], model.jnt_dofadr[joint]
            data.qpos[qa:qa + 4] = _quat(parent_R.T @ R[a, i])
            data.qvel[va:va + 3] = R[a, i].T @ (omega[a, i] - parent_w)   # the child's frame
    mujoco.mj_forward(model, data)
    return model, data, bodies


def run_mujoco(state, spheres, duration):
    """Run the strands of state in MuJoCo for duration; return their tips every SAMPLE_S."""
    import mujoco
    model, data, bodies = mujoco_chains(state, spheres)
    length = state['length']
    flat = bodies.ravel()
    mass = state['mass'].ravel()[:, None]
    couples = np.zeros(bodies.shape + (3,))
    every = int(round(SAMPLE_S / MUJOCO_DT))

    def tips():
        return chain_tips(data, bodies[:, -1], length[:, -1])
    out = []
    for step in range(int(round(duration / MUJOCO_DT))):
        mujoco.mj_step1(model, data)
        apply_air_damping(model, data, flat, state['air'] * mass)
        for a, b in enumerate(bodies):
            axes = np.ascontiguousarray(data.xmat[b].reshape(-1, 3, 3)[:, :, 2])
            chain_spring_couples(axes, state['R_head'], state['rest_rel'][a],
                                 state['offset'][a], state['k'][a], couples[a])
        data.xfrc_applied[flat, 3:] = couples.reshape(-1, 3)
        mujoco.mj_step2(model, data)
        if (step + 1) % every == 0:
            out.append(tips())
    return np.array(out)


def strand_state(sim, strands):
    """Return what MuJoCo needs of the strands (indices) of an articulated HairSimulator."""
    solver = sim.solver
    R_head = np.array(sim.head_pose[0], dtype=float)
    return {'R': solver.R[strands].copy(), 'omega': solver.omega[strands].copy(),
            'pos': sim.pos[strands].copy(), 'length': sim.length[strands].copy(),
            'mass': sim.mass[strands].copy(), 'k': solver.k[strands].copy(),
            'd': solver.d[strands].copy(), 'offset': solver.offset[strands].copy(),
            'rest_rel': solver.rest_rel[strands].copy(),
            'inertia_axial': solver.inertia_axial[strands].copy(), 'air': solver.air,
            'gravity': sim.params.gravity, 'R_head': R_head}


def last_fast(tips, speed):
    """
    Return (when the last interval in which a tip moved faster than speed ends, speeds).

    tips[j] is taken (j + 1) SAMPLE_S after the run began; the time is from then, and
    speeds[j] is the fastest tip between tips[j] and tips[j + 1].
    """
    v = np.linalg.norm(np.diff(tips, axis=0), axis=2).max(axis=1) / SAMPLE_S
    fast = np.nonzero(v > speed)[0]
    return (float((fast[-1] + 2) * SAMPLE_S) if len(fast) else 0.0), v


def _gale(dt):
    """Drive the stress bench's gale case at dt; return (sim, the still head, t at the stop)."""
    style = load_hairstyle(paths.shipped_style(STYLE))
    sim = HairSimulator(style, model='articulated')
    sim.set_wind(GALE[0], turbulence=GALE[1], seed=1)
    t = 0.0
    for i in range(int(round(GALE_S / dt))):
        t = (i + 1) * dt
        sim.set_head_pose(t, *violent(t))
        sim.step(dt)
    sim.set_wind([0.0, 0.0, 0.0])
    return sim, violent(t), t


def _hold(sim, hold, t, dt, duration):
    """Step sim with the head still for duration; return (tips every SAMPLE_S, slept at)."""
    every = int(round(SAMPLE_S / dt))
    tips, slept = [], None
    for i in range(int(round(duration / dt))):
        sim.set_head_pose(t + (i + 1) * dt, *hold)
        sim.step(dt)
        if slept is None and sim.sleeping:
            slept = (i + 1) * dt
        if (i + 1) % every == 0:
            tips.append(sim.pos[:, -1].copy())
    return np.array(tips), slept


def run_dt(dt, quick):
    """Return the record of one step size (and the tips for the plot)."""
    after = 6.0 if quick else AFTER_S
    sim, hold, t = _gale(dt)
    tol = sim.params.sleep_tolerance / sim.params.sleep_delay      # m/s
    as_in_stress = copy.deepcopy(sim)
    _, slept_with_springs = _hold(as_in_stress, hold, t, dt, after)
    sim.set_params(inter_strip=False)
    start = int(round(START_S / dt))
    _hold(sim, hold, t, dt, START_S)
    at_start = copy.deepcopy(sim)
    tips, slept_apart = _hold(sim, hold, t + start * dt, dt, after - START_S)
    # the late strands: a tip faster than the tolerance in the second before the window
    # ends (tips[k] is at its end)
    k = int(round((WINDOW_S - START_S) / SAMPLE_S)) - 1
    v = np.linalg.norm(np.diff(tips[k - int(1 / SAMPLE_S):k + 1], axis=0), axis=2) / SAMPLE_S
    late = np.nonzero(v.max(axis=0) > tol)[0]
    late = late[np.argsort(-v.max(axis=0)[late])][:MAX_STRANDS]
    late.sort()
    record = {'dt': dt, 'style': STYLE, 'sleep_speed_m_s': tol,
              'slept_s_after_stop_with_strip_springs': slept_with_springs,
              'slept_s_after_stop_without': slept_apart and slept_apart + START_S,
              'late_strands': late.tolist(), 'mujoco_from_s_after_stop': START_S,
              'run_s_after_stop': after}
    if not len(late):
        return record, None
    hs = tips[:, late]
    # the spheres where hair_sim's last substep placed them (the head is still)
    mj = run_mujoco(strand_state(at_start, late), np.array(at_start.bodies.spheres),
                    after - START_S)
    for name, x in (('hair_sim', hs), ('mujoco', mj)):
        fast, _ = last_fast(x, tol)
        record['%s_last_fast_s_after_stop' % name] = START_S + fast
        record['%s_still_moving_at_end' % name] = fast >= after - START_S - 0.5 * SAMPLE_S
        record['%s_speed_at_window_end_m_s' % name] = float(np.linalg.norm(
            x[k] - x[k - 1], axis=1).max() / SAMPLE_S)
    record['tip_gap_mm'] = []          # per late strand, at times after the stop
    for when in (1.0, 2.0, WINDOW_S - START_S, after - START_S):
        i = int(round(when / SAMPLE_S)) - 1
        record['tip_gap_mm'].append({
            's_after_stop': START_S + when,
            'mm': (1e3 * np.linalg.norm(hs[i] - mj[i], axis=1)).round(1).tolist()})
    return record, (hs, mj)


def run(quick=False, plots=None):
    """Run both failing steps of the gale (1/240 only if quick); return the records."""
    dts = [1 / 240] if quick else [1 / 240, 1 / 1000]
    records, curves = [], []
    for dt in progress(dts, 'fall'):
        record, tips = run_dt(dt, quick)
        records.append(record)
        curves.append((dt, record, tips))
    if plots:
        plot(curves, plots)
    return records


def plot(curves, directory):
    """Plot the fastest late tip after the stop, hair_sim and MuJoCo, per step size."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for (dt, record, tips), colour in zip(curves, ('C0', 'C1')):
        if tips is None:
            continue
        for x, style, who in zip(tips, ('-', '--'), ('hair_sim', 'MuJoCo')):
            _, v = last_fast(x, record['sleep_speed_m_s'])
            t = START_S + SAMPLE_S * (np.arange(len(v)) + 2)
            ax.semilogy(t, 1e3 * np.maximum(v, 1e-4), style, color=colour,
                        label='%s, gale at 1/%d s' % (who, round(1 / dt)))
    ax.axhline(1e3 * curves[0][1]['sleep_speed_m_s'], color='gray', lw=0.6)
    ax.axvline(WINDOW_S, color='red', lw=0.6)
    ax.set_xlabel('s after the 30 m/s gale stopped (head still, springs between strands off)')
    ax.set_ylabel('fastest late tip (mm/s)')
    ax.set_title('stress gale: strands still moving (red: end of the sleep window)', fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = save_figure(fig, '%s/fall.png' % directory)
    plt.close(fig)
    return path
