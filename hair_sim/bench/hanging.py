"""
The hanging-hair scene, in hair_sim and in MuJoCo, and what they say about each other.

Scene: a rigid head sphere, R = 0.1 m, at the origin. N strands with roots on a Fibonacci
lattice over the upper hemisphere (z_i = 1 - (i + 0.5) / N, azimuth i pi (3 - sqrt 5)),
0.1005 m from the origin along the normal, each straight along its normal and at rest at
t = 0; length 0.3 m in S equal segments; lambda = 1e-4 kg/m, EI = 1e-7 N m^2; the first
segment clamped. Air damping 5/s, gravity 9.81 m/s^2 along -z, frictionless head contact,
no hair-hair contact. Simulated for 2 s.

MuJoCo (a benchmark-only dependency: `make bench-deps`): one body per segment, a capsule
of the segment's length and mass (rod inertia), ball joints with stiffness EI / ds at the
segment starts, the first segment welded to the head, the implicit integrator, condim-1
(frictionless) contacts with the head sphere only, and the air damping applied as a force
-nu m v at every segment's centre each step.
"""

import math
import time

import numpy as np

from hair_sim.modeling.head import HeadModel

RADIUS = 0.1
ROOT_OFFSET = 0.1005
LENGTH = 0.3
LINEAR_DENSITY = 1e-4
BENDING_STIFFNESS = 1e-7
AIR_DAMPING = 5.0
GRAVITY = 9.81
DURATION = 2.0
CLAMP = 1e6                  # root_stiffness_scale that clamps the first segment
# A strand of radius 0.1 mm: lambda = rho pi r^2 and EI = E pi r^4 / 4 give these
FIBRE_RADIUS = 1e-4
FIBRE_DENSITY = LINEAR_DENSITY / (math.pi * FIBRE_RADIUS ** 2)
FIBRE_MODULUS = 4.0 * BENDING_STIFFNESS / (math.pi * FIBRE_RADIUS ** 4)


def roots_and_normals(n_strands):
    """Return the Fibonacci-lattice roots (N, 3) and their unit normals (N, 3)."""
    i = np.arange(n_strands)
    z = 1.0 - (i + 0.5) / n_strands
    azimuth = i * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    normals = np.stack([r * np.cos(azimuth), r * np.sin(azimuth), z], axis=1)
    return ROOT_OFFSET * normals, normals


def head_model():
    """Return the scene's head: one sphere of radius 0.1 m at the origin."""
    sphere = np.array([[0.0, 0.0, 0.0, RADIUS]])
    return HeadModel(name='hanging_scene_sphere', frame_id='head', scalp=sphere,
                     body=np.zeros((0, 4)), projection_sphere=np.array([0.0, 0.0, 0.0, 0.05]),
                     hairline={'front_x': 1.0, 'front_z': -1.0, 'back_x': -1.0, 'back_z': -1.0})


def rest_strands(n_strands, n_segments):
    """Return the straight strands (N, S + 1, 3) along their normals."""
    roots, normals = roots_and_normals(n_strands)
    s = np.linspace(0.0, LENGTH, n_segments + 1)
    return roots[:, None, :] + s[None, :, None] * normals[:, None, :]


def scene_params(model):
    """Return the PhysicsParams of the scene for a hair_sim model."""
    return dict(model=model, hairs_per_strand=1.0, hair_radius=FIBRE_RADIUS,
                hair_density=FIBRE_DENSITY, youngs_modulus=FIBRE_MODULUS, stiffness_scale=1.0,
                root_stiffness_scale=CLAMP, damping=0.0, air_damping=AIR_DAMPING,
                gravity=GRAVITY, gravity_compensation=False, inter_strip=False,
                collisions=True, sleep_tolerance=0.0, drag_coefficient=0.0,
                contact_friction=0.0)             # the scene: frictionless head contact


def run_hair_sim(model, n_strands, n_segments, dt, duration=DURATION):
    """Run the scene in hair_sim; return (tips at the end (N, 3), wall s per simulated s)."""
    from hair_sim.physics.simulator import HairSimulator
    sim = HairSimulator.from_strands(rest_strands(n_strands, n_segments), head_model(),
                                     **scene_params(model))
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    steps = int(round(duration / dt))
    sim.step(dt)                                  # compile and place (not timed)
    sim.reset()
    sim.time = 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step(dt)
    wall = time.perf_counter() - t0
    return sim.pos[:, -1].copy(), wall / duration, sim


def mujoco_xml(n_strands, n_segments, capsule_radius=5e-4):
    """Return the MJCF of the scene: capsule chains on ball joints, the first welded."""
    roots, normals = roots_and_normals(n_strands)
    ds = LENGTH / n_segments
    m = LINEAR_DENSITY * ds
    i_perp = m * ds * ds / 12.0
    i_axial = 0.5 * m * capsule_radius ** 2
    k = BENDING_STIFFNESS / ds
    out = ['<mujoco model="hanging_hair">',
           '<option timestep="0.001" gravity="0 0 %g" integrator="implicitfast"/>' % -GRAVITY,
           '<size memory="2G"/>',
           '<default><geom contype="1" conaffinity="0" condim="1" margin="0"/></default>',
           '<worldbody>',
           '<geom name="head" type="sphere" size="%g" contype="0" conaffinity="1"/>' % RADIUS]
    for s in range(n_strands):
        n = normals[s]
        # orientation: the body's z axis along the normal (quaternion of the minimal turn)
        axis = np.cross([0.0, 0.0, 1.0], n)
        sn = np.linalg.norm(axis)
        ang = math.atan2(sn, n[2])
        axis = axis / sn if sn > 1e-12 else np.array([1.0, 0.0, 0.0])
        q = [math.cos(ang / 2)] + list(math.sin(ang / 2) * axis)
        inner = []
        for j in range(n_segments):
            pos = '%g %g %g' % tuple(roots[s]) if j == 0 else '0 0 %g' % ds
            quat = ' quat="%g %g %g %g"' % tuple(q) if j == 0 else ''
            joint = '' if j == 0 else '<joint type="ball" stiffness="%g" damping="0"/>' % k
            inner.append('<body pos="%s"%s>%s<inertial pos="0 0 %g" mass="%g" '
                         'diaginertia="%g %g %g"/><geom type="capsule" fromto="0 0 0 0 0 %g" '
                         'size="%g" mass="0"/>' % (pos, quat, joint, ds / 2, m, i_perp, i_perp,
                                                   i_axial, ds, capsule_radius))
        out.append(''.join(inner) + '</body>' * n_segments)
    out += ['</worldbody>', '</mujoco>']
    return '\n'.join(out)


def run_mujoco(n_strands, n_segments, dt, duration=DURATION):
    """Run the scene in MuJoCo; return (tips at the end (N, 3), wall s per simulated s)."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(mujoco_xml(n_strands, n_segments))
    model.opt.timestep = dt
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ds = LENGTH / n_segments
    mass = LINEAR_DENSITY * ds
    steps = int(round(duration / dt))
    root = model.body_rootid
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step1(model, data)
        # air damping: -nu m v at each segment's centre of mass; cvel is each body's
        # velocity (angular, linear) about the subtree centre of mass of its root
        w, v = data.cvel[1:, :3], data.cvel[1:, 3:]
        r = data.xipos[1:] - data.subtree_com[root[1:]]
        data.xfrc_applied[1:, :3] = -AIR_DAMPING * mass * (v + np.cross(w, r))
        mujoco.mj_step2(model, data)
    wall = time.perf_counter() - t0
    # tips: the end of every strand's last capsule
    tips = []
    for s in range(n_strands):
        b = 1 + s * n_segments + n_segments - 1
        tips.append(data.xpos[b] + data.xmat[b].reshape(3, 3)[:, 2] * ds)
    return np.array(tips), wall / duration


def rms(a, b):
    """Return the RMS distance between matching rows of a and b."""
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def _unstable(tips):
    return tips is None or not np.all(np.isfinite(tips)) or np.abs(tips).max() > 10.0


# MuJoCo's reference step per size: the ball-joint chain is unstable at twice these
# (50 x 10 at 1/2000 s, 50 x 20 at 1/8000 s: NaN warnings and a reset in MuJoCo)
REFERENCE_DT = {10: 1 / 4000, 20: 1 / 16000}


def run(quick=False, plots=None):
    """
    Run the hanging-hair scene in both hair_sim models and MuJoCo; return tips and costs.

    The reference is MuJoCo at REFERENCE_DT. Each record gives the tip RMS against it, the
    mean tip height and wall seconds per simulated second (one core, stepping only). The
    speed rows step larger scenes: MuJoCo for the first 0.02 s at its reference step (the
    whole scene would take it hours at 1000 x 20; the strands reach the head, and its
    contacts, only later), hair_sim at one step per 60 Hz frame for the whole 2 s
    (the articulated model's cost falls as the strands come to rest: each takes only the
    substeps it needs).
    """
    from hair_sim.physics.simulator import SimulationDiverged
    sizes = [(50, 10)] if quick else [(50, 10), (50, 20)]
    dts = [1 / 60, 1 / 240] if quick else [1 / 60, 1 / 120, 1 / 240, 1 / 1000]
    try:
        import mujoco  # noqa: F401
        have_mujoco = True
    except ImportError:
        have_mujoco = False
    records = []
    for n_strands, n_segments in sizes:
        ref = None
        if have_mujoco:
            dt = REFERENCE_DT[n_segments]
            tips, cost = run_mujoco(n_strands, n_segments, dt)
            bad = _unstable(tips) or tips[:, 2].mean() > 0.0    # a reset leaves them up
            records.append({'solver': 'mujoco', 'strands': n_strands, 'segments': n_segments,
                            'dt': dt, 'stable': not bad, 'wall_s_per_sim_s': cost,
                            'mean_tip_z': None if bad else float(tips[:, 2].mean())})
            ref = None if bad else tips
        for model in ('articulated', 'anjyo'):
            for dt in dts:
                try:
                    tips, cost, _ = run_hair_sim(model, n_strands, n_segments, dt)
                    bad = _unstable(tips)
                except SimulationDiverged:
                    tips, cost, bad = None, None, True
                records.append({'solver': 'hair_sim ' + model, 'strands': n_strands,
                                'segments': n_segments, 'dt': dt, 'stable': not bad,
                                'wall_s_per_sim_s': cost,
                                'mean_tip_z': None if bad else float(tips[:, 2].mean()),
                                'tip_rms_vs_mujoco_m': None if bad or ref is None
                                else rms(tips, ref),
                                # the strands near the top start on an unstable balance:
                                # which side they fall to is chaotic, the median is not
                                'tip_median_vs_mujoco_m': None if bad or ref is None
                                else float(np.median(np.linalg.norm(tips - ref, axis=1)))})
    for n_big in ([200] if quick else [200, 1000]):
        if have_mujoco:
            _, cost = run_mujoco(n_big, 20, REFERENCE_DT[20], duration=0.02)
            records.append({'solver': 'mujoco', 'strands': n_big, 'segments': 20,
                            'dt': REFERENCE_DT[20], 'wall_s_per_sim_s': cost,
                            'speed_only': True})
        for model in ('articulated', 'anjyo'):
            _, cost, _ = run_hair_sim(model, n_big, 20, 1 / 60)
            records.append({'solver': 'hair_sim ' + model, 'strands': n_big, 'segments': 20,
                            'dt': 1 / 60, 'wall_s_per_sim_s': cost, 'speed_only': True})
    if plots:
        _plot(records, plots)
    return records


def _plot(records, directory):
    import os

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from hair_sim.fileio import save_figure
    size = (records[0]['strands'], records[0]['segments'])
    records = [r for r in records if (r['strands'], r['segments']) == size]
    fig, ax = plt.subplots(figsize=(6, 4))
    for solver, marker in (('hair_sim articulated', 'o'), ('hair_sim anjyo', 's')):
        rs = [r for r in records if r['solver'] == solver and r.get('tip_rms_vs_mujoco_m')]
        if rs:
            ax.loglog([r['tip_rms_vs_mujoco_m'] * 1e3 for r in rs],
                      [r['wall_s_per_sim_s'] for r in rs], marker + '-', label=solver)
            for r in rs:
                xy = (r['tip_rms_vs_mujoco_m'] * 1e3, r['wall_s_per_sim_s'])
                ax.annotate('1/%d' % round(1 / r['dt']), xy, fontsize=7)
    mj = [r for r in records if r['solver'] == 'mujoco' and r.get('stable')
          and not r.get('speed_only')]
    for r in mj:
        ax.axhline(r['wall_s_per_sim_s'], color='k', ls='--', lw=0.8,
                   label='MuJoCo at 1/%d (the reference)' % round(1 / r['dt']))
    ax.axvline(3.0, color='r', ls=':', lw=0.8, label='3 mm')
    ax.set_xlabel('tip RMS against MuJoCo at 2 s (mm)')
    ax.set_ylabel('wall s per simulated s (one core)')
    ax.set_title('hanging hair, %d x %d' % (records[0]['strands'], records[0]['segments']))
    ax.legend(fontsize=7)
    save_figure(fig, os.path.join(directory, 'hanging_work_precision.png'))
    plt.close(fig)
