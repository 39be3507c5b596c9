"""
hair_sim_bench turn: the hanging hair on a head that turns and moves, against MuJoCo.

The issue's hanging scene (hanging.py) keeps the head still. Here the head's motion is
the strands' base motion, as it is on an avatar: the lag of the tips must come out of the
chain's dynamics. The scene hangs still for HOLD seconds (the strands fall and drape),
then the head makes one of MOTIONS: in `seconds` it turns by `angle` about `axis` through
the sphere's centre and slides `shift` (m, a vector), both from rest to rest along a
quintic (continuous acceleration), then holds still until END. 'turn' is mostly a yaw,
partly a roll, with a slide sideways; 'nod' a pitch with a rise; 'fast turn' the turn
in two thirds of the time, violent enough to throw strands against the head.

hair_sim is fed the head's pose every step (set_head_pose), and estimates the velocities
and accelerations from those poses, with `motion_smoothing` 0 (the poses' own finite
differences) and with its default, 0.02 s (a low-pass of the head's velocity that holds
out a tracker's noise, hair_sim_bench jitter).

MuJoCo: the sphere and the capsule chains are carried by a head body on a slide joint
(along the shift) and a hinge (about the axis) (hanging.mujoco_xml with head_joints).
The head is prescribed: HEAD_INERTIA is over 1e7 times the hair's mass (1.5 g at 50 x
10) and inertia, and every step its
joints get the generalised forces that give them the motion's exact accelerations (with a
stiff PD on what is left), so the chains take the base motion through their joints alone.

Per run: the tip RMS and median distance from MuJoCo (at half its step in the full run)
every SAMPLE_EVERY seconds from HOLD to END, and the reference's own median tip
displacement since HOLD (how far the motion carried the tips).
"""

from collections import namedtuple
import math
import time

import numpy as np

from hair_sim.bench import hanging
from hair_sim.bench.common import progress

HOLD = 2.0                      # s the head is still at first
END = 3.5                       # s
SAMPLE_EVERY = 0.05             # s: a multiple of every step run here
# A motion: in `seconds` (twice a multiple of SAMPLE_EVERY, so that its middle is
# sampled), a turn by `angle` (rad) about the unit `axis` and a slide by `shift` (m).
Motion = namedtuple('Motion', ['seconds', 'angle', 'axis', 'shift'])
_TILTED = (0.3 / math.sqrt(1.09), 0.0, 1.0 / math.sqrt(1.09))
MOTIONS = {
    'turn': Motion(0.3, math.pi / 2, _TILTED, (0.05, 0.0, 0.0)),
    'nod': Motion(0.4, math.pi / 3, (0.0, 1.0, 0.0), (0.0, 0.0, 0.05)),
    'fast turn': Motion(0.2, math.pi / 2, _TILTED, (0.05, 0.0, 0.0)),
}
HEAD_INERTIA = 1e4              # kg and kg m^2 of MuJoCo's head body
HEAD_GAIN = (1e4, 2e2)          # MuJoCo head's PD on the residual: 1/s^2, 1/s


def table_times(motion):
    """Return {phase: time} the table shows: before, mid-motion, its end, 0.2 s on, END."""
    return {'before': HOLD, 'mid': round(HOLD + motion.seconds / 2, 9),
            'end': round(HOLD + motion.seconds, 9),
            'after': round(HOLD + motion.seconds + 0.2, 9), 'last': END}


def progress_of_motion(motion, t):
    """Return the motion's share done at t, and its first two time derivatives (quintic)."""
    T = motion.seconds
    u = min(max((t - HOLD) / T, 0.0), 1.0)
    return (u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u),
            30.0 * u * u * (1.0 - u) ** 2 / T,
            60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / T ** 2)


def head_pose(motion, t):
    """Return the head's pose at t: position (3,) and quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation
    s = progress_of_motion(motion, t)[0]
    return (s * np.array(motion.shift),
            Rotation.from_rotvec(motion.angle * s * np.array(motion.axis)).as_quat())


def sample_times():
    """Return the times the tips are compared at."""
    n = int(round((END - HOLD) / SAMPLE_EVERY))
    return [round(HOLD + k * SAMPLE_EVERY, 9) for k in range(n + 1)]


def _sample_steps(dt):
    """Return {step index: time} of the samples for a step dt (a divisor of SAMPLE_EVERY)."""
    out = {}
    for t in sample_times():
        i = int(round(t / dt))
        if abs(i * dt - t) > 1e-9:
            raise ValueError('sample time %g is not a multiple of dt %g' % (t, dt))
        out[i] = t
    return out


def run_hair_sim(motion, model, n_strands, n_segments, dt, motion_smoothing):
    """
    Run the scene in hair_sim; return ({t: tips (N, 3)}, wall s per simulated s).

    The poses are made before the clock starts (scipy took some 0.1-0.3 ms a pose, half
    the cost at 1/1000 s); feeding them is timed, as a node's callbacks would be.
    """
    from hair_sim.physics.simulator import HairSimulator
    params = dict(hanging.scene_params(model), motion_smoothing=motion_smoothing)
    sim = HairSimulator.from_strands(hanging.rest_strands(n_strands, n_segments),
                                     hanging.head_model(), **params)
    sim.set_head_pose(0.0, *head_pose(motion, 0.0))
    samples = _sample_steps(dt)
    steps = int(round(END / dt))
    poses = [head_pose(motion, i * dt) for i in range(steps + 1)]
    tips = {}
    t0 = time.perf_counter()
    for i in range(1, steps + 1):
        sim.set_head_pose(i * dt, *poses[i])
        sim.step(dt)
        if i in samples:
            tips[samples[i]] = sim.pos[:, -1].copy()
    return tips, (time.perf_counter() - t0) / END


def run_mujoco(motion, n_strands, n_segments, dt):
    """
    Run the scene in MuJoCo, the head prescribed; return ({t: tips}, wall s per sim. s).

    Also returns the largest distance (m, at the roots' 0.1 m) between the head's joints
    and the prescribed motion, to show it was followed.
    """
    import mujoco
    shift = math.sqrt(sum(x * x for x in motion.shift))
    joints = ('<joint type="slide" axis="%.17g %.17g %.17g"/>'
              '<joint type="hinge" axis="%.17g %.17g %.17g"/>'
              '<inertial pos="0 0 0" mass="%g" diaginertia="%g %g %g"/>'
              % (tuple(np.array(motion.shift) / shift) + tuple(motion.axis)
                 + (HEAD_INERTIA,) * 4))
    model = mujoco.MjModel.from_xml_string(
        hanging.mujoco_xml(n_strands, n_segments, head_joints=joints))
    model.opt.timestep = dt
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ds = hanging.LENGTH / n_segments
    mass = hanging.LINEAR_DENSITY * ds
    amplitude = np.array([shift, motion.angle])
    kp, kv = HEAD_GAIN
    samples = _sample_steps(dt)
    tip_bodies = 2 + np.arange(n_strands) * n_segments + n_segments - 1   # (0 world, 1 head)
    tips, worst = {}, 0.0
    t0 = time.perf_counter()
    for i in range(int(round(END / dt))):
        mujoco.mj_step1(model, data)
        # air damping on the segments (bodies 2 on), as hanging.run_mujoco
        hanging.apply_air_damping(model, data, slice(2, None), hanging.AIR_DAMPING * mass)
        # the head: the motion's acceleration (its own inertia; the hair's is under 1e-7)
        # plus the PD on the residual, over the velocity-product and gravity forces
        s, ds_dt, d2s = progress_of_motion(motion, i * dt)
        wanted = amplitude * d2s + kp * (amplitude * s - data.qpos[:2]) + \
            kv * (amplitude * ds_dt - data.qvel[:2])
        data.qfrc_applied[:2] = HEAD_INERTIA * wanted + data.qfrc_bias[:2]
        mujoco.mj_step2(model, data)
        if i + 1 in samples:
            s = progress_of_motion(motion, (i + 1) * dt)[0]
            off = np.abs(data.qpos[:2] - amplitude * s) * [1.0, hanging.ROOT_OFFSET]
            worst = max(worst, float(off.max()))
            tips[samples[i + 1]] = hanging.chain_tips(data, tip_bodies,
                                                      np.full(n_strands, ds))
    return tips, (time.perf_counter() - t0) / END, worst


def _series(tips, reference):
    """Return the [t, RMS m, median m] rows of tips against the reference's."""
    out = []
    for t in sample_times():
        if t in tips and reference is not None:
            rms, median = hanging.tip_distances(tips[t], reference[t])
            out.append([t, rms, median])
    return out


def _at(series, t):
    """Return (RMS, median) of a series at time t, or (None, None)."""
    for row in series:
        if abs(row[0] - t) < 1e-9:
            return row[1], row[2]
    return None, None


def _record(name, solver, size, dt, smoothing, series, cost, **more):
    record = {'motion': name, 'solver': solver, **size, 'dt': dt,
              'motion_smoothing_s': smoothing, 'wall_s_per_sim_s': cost, **more}
    for phase, t in table_times(MOTIONS[name]).items():
        record['tip_rms_m_' + phase], record['tip_median_m_' + phase] = _at(series, t)
    record['series'] = series
    return record


def run(quick=False, plots=None):
    """
    Run every motion in MuJoCo and in both hair_sim models; return one record per run.

    The full run: 50 x 10, every motion, MuJoCo at REFERENCE_DT and half of it (the
    reference, with how far halving moved it); the articulated model at 1/60, 1/240 and
    1/1000 s, each without and with the default motion smoothing; the thesis model at the
    default step. --quick: 10 x 10, the turn alone, MuJoCo once, the articulated model at
    1/60 and 1/240 s.
    """
    from hair_sim.physics.params import PhysicsParams
    from hair_sim.physics.simulator import DEFAULT_DT, SimulationDiverged
    n_strands, n_segments = (10, 10) if quick else (50, 10)
    size = {'strands': n_strands, 'segments': n_segments}
    default_smoothing = PhysicsParams().motion_smoothing
    runs = [('articulated', h, s) for h in ([1 / 60, 1 / 240] if quick else
                                            [1 / 60, 1 / 240, 1 / 1000])
            for s in (0.0, default_smoothing)]
    if not quick:
        runs.append(('anjyo', DEFAULT_DT, default_smoothing))
    records = []
    for name in progress(['turn'] if quick else list(MOTIONS), 'turn'):
        motion = MOTIONS[name]
        dt = hanging.REFERENCE_DT[n_segments]
        coarse, cost, worst = run_mujoco(motion, n_strands, n_segments, dt)
        reference, self_series = coarse, []
        if not quick:
            dt /= 2
            reference, cost, worst_fine = run_mujoco(motion, n_strands, n_segments, dt)
            worst = max(worst, worst_fine)
            self_series = _series(coarse, reference)
        moved = [[t, float(np.median(np.linalg.norm(reference[t] - reference[HOLD],
                                                    axis=1)))] for t in sample_times()]
        # (its columns: how far it moved when its step was halved; none in --quick)
        records.append(_record(name, 'mujoco', size, dt, None, self_series, cost,
                               head_off_motion_m=worst, tips_moved_median=moved))
        for model, h, smoothing in runs:
            try:
                tips, cost = run_hair_sim(motion, model, n_strands, n_segments, h, smoothing)
                series = _series(tips, reference)
            except SimulationDiverged:
                series, cost = [], None
            records.append(_record(name, 'hair_sim ' + model, size, h, smoothing, series,
                                   cost, stable=bool(series)))
    if plots:
        _plot(records, plots)
    return records


def _plot(records, directory):
    """Plot every run's tip RMS from MuJoCo against time, a panel per motion."""
    import os

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from hair_sim.fileio import save_figure
    names = list(dict.fromkeys(r['motion'] for r in records))
    fig, axes = plt.subplots(len(names), 1, figsize=(11, 4 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        motion = MOTIONS[name]
        mine = [r for r in records if r['motion'] == name]
        reference = mine[0]
        ax.axvspan(HOLD, HOLD + motion.seconds, color='0.9', label='head moving')
        t, moved = np.array(reference['tips_moved_median']).T
        ax.plot(t, 1e3 * moved, 'k--', lw=0.8,
                label='MuJoCo: median tip motion since %g s' % HOLD)
        if reference['series']:
            t, rms, _ = np.array(reference['series']).T
            ax.plot(t, 1e3 * rms, 'k:', lw=0.8, label='tip RMS of MuJoCo at twice its step')
        for r in mine[1:]:
            if not r['series']:
                continue
            t, rms, _ = np.array(r['series']).T
            ax.plot(t, 1e3 * rms, '-' if r['motion_smoothing_s'] == 0.0 else '--',
                    label='tip RMS of %s 1/%d s, motion_smoothing %g s'
                    % (r['solver'], round(1 / r['dt']), r['motion_smoothing_s']))
        ax.set_yscale('log')
        ax.set_xlabel('time (s)')
        ax.set_ylabel('from MuJoCo at half its step (mm)')
        ax.set_title('hanging hair, %d x %d: %s, %d degrees and %g cm in %g s'
                     % (reference['strands'], reference['segments'], name,
                        round(math.degrees(motion.angle)),
                        100 * math.sqrt(sum(x * x for x in motion.shift)), motion.seconds))
        ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    save_figure(fig, os.path.join(directory, 'turn_vs_mujoco.png'))
    plt.close(fig)
