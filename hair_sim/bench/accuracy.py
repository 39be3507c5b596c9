"""
hair_sim_bench accuracy: work against precision of both strand models.

Every scenario runs the thesis model (`anjyo`) with both of its integrators and the
articulated chain (`articulated`, one integrator), on the same tables and plots:

1. pendulum: one segment with hinge spring, against the exact ODE (scipy DOP853, rtol
   1e-10) of the same equation; both models are this pendulum exactly (a rod on a joint
   with a spring and a damper towards hanging down);
2. chain: a 10-segment strand released from horizontal, against an independent exact
   articulated chain: the Lagrangian of 10 rigid rods integrated by scipy, with gravity,
   damping and each model's own springs. For anjyo the absolute-angle hinges of eq. 3
   and each segment's own damping (the thesis' springs, so the difference is its dynamics:
   each segment swings about its start as if that were fixed and carries neither the
   inertia nor the weight of everything below it); for articulated the relative (Hencky)
   springs and joint dampers d = damping x the inertia beyond the joint;
3. hairstyle: the sample style under scripted head motion and wind, against the same model
   (and integrator) at dt = 1/24000 s.
"""

import math

import numpy as np

from hair_sim import load_hairstyle, load_head, paths
from hair_sim.bench.common import cpu_time, DT_FULL, DT_QUICK, progress, save_figure
from hair_sim.physics.params import INTEGRATORS, PhysicsParams
from hair_sim.bench.scenarios import demo
from hair_sim.physics import SimulationDiverged
from hair_sim.physics.simulator import HairSimulator


def _head():
    return load_head(paths.shipped_head('default_adult'))


# (model, integrator) pairs every scenario runs; the articulated chain has one integrator
VARIANTS = [('anjyo', integ) for integ in INTEGRATORS] + [('articulated', '-')]


def _model_params(model, integrator):
    """Return the PhysicsParams changes that select a variant."""
    return dict(model=model) if model == 'articulated' else dict(model=model,
                                                                 integrator=integrator)


def _bare(rest, model, integrator, **params):
    # no drag: the articulated chain feels still air (the references have no air)
    base = dict(collisions=False, inter_strip=False, gravity_compensation=False,
                drag_coefficient=0.0, **_model_params(model, integrator))
    base.update(params)
    return HairSimulator.from_strands(rest, _head(), **base)


def _run_sampled(sim, dt, duration, every, motion=None):
    """
    Step sim for `duration`, recording positions every `every` seconds (a multiple of dt).

    Returns (sample times, positions (T, ...), ok): ok means finite, and the step guard
    (MAX_TURN) fired on under 1 % of segment-steps (an unstable run trips it every step).
    """
    m = int(round(every / dt))
    if abs(m * dt - every) > 1e-9 * every:
        raise ValueError('sample period %g is not a multiple of dt %g' % (every, dt))
    n = int(round(duration / dt))
    times, out = [0.0], [sim.pos.copy()]
    for i in range(1, n + 1):
        t = i * dt
        if motion is not None:
            p, q = motion(t)
            sim.set_head_pose(t, p, q)
        try:
            sim.step(dt)
        except SimulationDiverged:
            return np.array(times), np.array(out), False
        if not np.all(np.isfinite(sim.pos)):
            return np.array(times), np.array(out), False
        if i % m == 0:
            times.append(t)
            out.append(sim.pos.copy())
    clamps = sim.counters['turn_clamps']
    return np.array(times), np.array(out), clamps <= 0.01 * n * sim.length.size


def _errors(a, b):
    d = np.linalg.norm(a - b, axis=-1)
    return float(np.sqrt(np.mean(d ** 2))), float(np.mean(d[-1]))


# ------------------------------------------------------------------ 1. pendulum
def pendulum_reference(length, amplitude, duration, params, damping_rate=None):
    """
    Dense exact solution of I th'' = -k th - m g (l/2) sin th - gamma I th' (th from down).

    gamma is damping_rate, by default params.damping (eq. 1's gamma / I).
    """
    gamma = params.damping if damping_rate is None else damping_rate
    from scipy.integrate import solve_ivp
    m = params.linear_density * length
    inertia = m * length ** 2 / 3.0
    k = params.bending_stiffness / length

    def rhs(_t, y):
        th, w = y
        return [w, (-k * th - m * params.gravity * length / 2 * math.sin(th)) / inertia
                - gamma * w]

    sol = solve_ivp(rhs, (0.0, duration), [amplitude, 0.0], method='DOP853', rtol=1e-10,
                    atol=1e-12, dense_output=True)

    def tip(times):
        th = sol.sol(times)[0]
        return np.stack([np.sin(th) * length, np.zeros_like(th), -np.cos(th) * length], -1)
    return tip


def _bare_records(scenario, rest, start, refs, dts, duration, scored=slice(None)):
    """
    Release one bare strand at every dt with every variant and score it.

    The strand has rest shape `rest` and starts along directions `start`; its vertices
    `scored` are compared with refs[model](times) at every step.
    """
    root = rest[0, 0]
    out = []

    def released(model, integ):
        sim = _bare(rest, model, integ)
        sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
        sim.set_directions(start)
        return sim

    for model, integ in VARIANTS:
        # compile first (not timed): with an empty numba cache the first dt's cost was
        # 84 times its cost with the kernels compiled
        _run_sampled(released(model, integ), max(dts), 3 * max(dts), max(dts))
        for dt in progress(dts, '%s %s %s' % (scenario, model, integ)):
            (times, pos, ok), cost = cpu_time(_run_sampled, released(model, integ), dt,
                                              duration, dt)
            # a run that tripped the step guard is scored (and marked unstable); one that
            # diverged has no positions to score
            complete = len(times) == int(round(duration / dt)) + 1
            rms, final = _errors(pos[:, 0, scored] - root, refs[model](times)) if complete \
                else (float('nan'), float('nan'))
            out.append({'scenario': scenario, 'model': model, 'integrator': integ, 'dt': dt,
                        'cost_s_per_sim_s': cost / duration, 'rms_error_m': rms,
                        'final_error_m': final, 'stable': ok})
    return out


def pendulum_records(dts, duration):
    """Return the records of scenario 1 for every integrator and dt."""
    length, amp = 0.03, 0.3
    refs = {'anjyo': pendulum_reference(length, amp, duration, PhysicsParams()),
            'articulated': articulated_pendulum_reference(length, amp, duration,
                                                          PhysicsParams())}
    root = np.array([0.0, 0.0, 1.0])
    start = np.array([[[math.sin(amp), 0.0, -math.cos(amp)]]])
    tips = {model: (lambda times, ref=ref: ref(times)[:, None]) for model, ref in refs.items()}
    return _bare_records('pendulum', np.array([[root, root + [0, 0, -length]]]), start,
                         tips, dts, duration, slice(1, 2))


# ------------------------------------------------------------------ 2. chain
def chain_reference(n, length, duration, params, springs='absolute', joint_damping_share=1.0,
                    air_damping=0.0, base=None, root_stiffness_scale=1.0, hanging=False):
    """
    Exact planar chain of n rods, absolute angles phi from the horizontal (y up).

    springs 'absolute': each rod's hinge pulls it towards hanging down, -k (phi_i - rest),
    and each rod is damped on its own angular velocity, -damping (m l^2 / 3) phi_i' (eqs.
    1-3). 'relative': a spring k on each joint's relative angle (the first against the
    fixed base), V = k/2 sum (phi_i - phi_{i-1})^2, and joint dampers d_i =
    joint_damping_share x damping x the inertia of the rods beyond joint i about it,
    hanging straight down (Rayleigh function sum d_i (phi_i' - phi_{i-1}')^2 / 2).
    air_damping (1/s): a force -air_damping m v on every rod's centre (its generalized
    force is -air_damping times the translational part of the mass matrix times phi').
    base (relative springs only): t -> (beta, beta'), the base turning about the root in
    the chain's plane, phi-wise (the first joint's angle is phi_1 - beta - rest, its
    damper works on phi_1' - beta'); root_stiffness_scale multiplies the first joint's k
    (a stiff first joint makes the system stiff: it is then integrated by Radau). The
    chain starts at rest, horizontal, or with `hanging` hanging straight down.
    """
    from scipy.integrate import solve_ivp
    m = params.linear_density * length
    k = params.bending_stiffness / length
    k_joint = np.full(n, k)
    k_joint[0] *= root_stiffness_scale
    i_end = m * length ** 2 / 3.0
    i_c = m * length ** 2 / 12.0
    rest = -math.pi / 2
    # joint i's relative angle is (diff @ phi)[i] - offset[i]
    diff = np.eye(n) - np.eye(n, k=-1)
    offset = np.zeros(n)
    offset[0] = rest
    beyond = np.array([m * sum((j - i + 0.5) ** 2 * length ** 2 + length ** 2 / 12.0
                               for j in range(i, n)) for i in range(n)])
    d_joint = joint_damping_share * params.damping * beyond
    # a[k, i]: lever of rod i's angle in the position of rod k's centre
    a = np.zeros((n, n))
    for kk in range(n):
        a[kk, :kk] = length
        a[kk, kk] = length / 2
    c = (m * a[:, :, None] * a[:, None, :]).sum(axis=0)       # c_ij = sum_k m a_ki a_kj
    g_lever = m * a.sum(axis=0)                               # sum_k m a_ki

    def rhs(t, y):
        phi, w = y[:n], y[n:]
        between = phi[:, None] - phi[None, :]
        M = c * np.cos(between) + np.diag(np.full(n, i_c))
        if springs == 'absolute':
            q = -k * (phi - rest) - params.damping * i_end * w
        else:
            rel = diff @ phi - offset
            rel_w = diff @ w
            if base is not None:
                beta, beta_rate = base(t)
                rel[0] -= beta
                rel_w[0] -= beta_rate
            q = -diff.T @ (k_joint * rel) - diff.T @ (d_joint * rel_w)
        q = q - params.gravity * np.cos(phi) * g_lever - air_damping * (c * np.cos(between)) @ w
        rhs_q = q - (c * np.sin(between) * w[None, :] ** 2).sum(axis=1)
        return np.concatenate([w, np.linalg.solve(M, rhs_q)])

    y0 = np.zeros(2 * n)
    if hanging:
        y0[:n] = rest
    # (hanging, the start is an equilibrium: the derivative there is 0 and the first
    # step guessed from it is so long that the trial states overflow)
    sol = solve_ivp(rhs, (0.0, duration), y0,
                    method='DOP853' if root_stiffness_scale <= 10.0 else 'Radau',
                    rtol=1e-10, atol=1e-12, dense_output=True,
                    first_step=1e-5 if hanging else None)

    def vertices(times):
        phi = sol.sol(times)[:n].T                                # (T, n)
        steps = np.stack([np.cos(phi), np.zeros_like(phi), np.sin(phi)], axis=-1) * length
        return np.concatenate([np.zeros((len(times), 1, 3)), np.cumsum(steps, axis=1)], 1)
    return vertices


def articulated_pendulum_reference(length, amplitude, duration, params):
    """
    Return pendulum_reference with the articulated model's damping law for one rod.

    The joint damper gives JOINT_DAMPING_SHARE x damping x I; the drag at the centre, at the
    model's air_damping_rate, a torque of that rate times m (l/2)^2 = 3/4 I.
    """
    from hair_sim.physics.solvers import articulated
    air = articulated.ArticulatedSolver.air_damping_rate(params)
    rate = articulated.JOINT_DAMPING_SHARE * params.damping + 0.75 * air
    return pendulum_reference(length, amplitude, duration, params, damping_rate=rate)


def articulated_chain_reference(n, length, duration, params, base=None, hanging=False):
    """Return chain_reference with the articulated model's springs and damping law."""
    from hair_sim.physics.solvers import articulated
    return chain_reference(n, length, duration, params, springs='relative',
                           joint_damping_share=articulated.JOINT_DAMPING_SHARE,
                           air_damping=articulated.ArticulatedSolver.air_damping_rate(params),
                           base=base, root_stiffness_scale=params.root_stiffness_scale,
                           hanging=hanging)


def chain_records(dts, duration):
    """Return the records of scenario 2 (10 segments from horizontal), every integrator/dt."""
    n, length = 10, 0.03
    refs = {'anjyo': chain_reference(n, length, duration, PhysicsParams()),
            'articulated': articulated_chain_reference(n, length, duration, PhysicsParams())}
    root = np.array([0.0, 0.0, 1.0])
    rest = np.array([root + [0, 0, -length * j] for j in range(n + 1)])[None]
    return _bare_records('chain', rest, np.tile([1.0, 0.0, 0.0], (1, n, 1)), refs, dts,
                         duration)


# ------------------------------------------------------------------ 3. hairstyle
def hairstyle_records(dts, duration, ref_dt=1.0 / 24000):
    """
    Return the records of scenario 3: the sample style, scripted head motion and wind.

    The reference is the same solver at ref_dt (1/24000 s: every tested dt is a multiple of
    it); positions are compared every 1/gcd seconds, a time every run steps onto.
    """
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    rates = [int(round(1 / dt)) for dt in dts]
    every = 1.0 / math.gcd(*rates)

    def run(model, integ, dt):
        sim = HairSimulator(style, **_model_params(model, integ))
        sim.set_head_pose(0.0, *demo(0.0))
        sim.set_wind([3.0, 1.0, 0.0], turbulence=0.3, seed=1)
        return cpu_time(_run_sampled, sim, dt, duration, every, motion=demo)

    out = []
    for model, integ in VARIANTS:
        (_, ref, _), _ = run(model, integ, ref_dt)
        for dt in progress(dts, 'hairstyle %s %s' % (model, integ)):
            (_, pos, ok), cost = run(model, integ, dt)
            rms, final = _errors(pos, ref) if ok else (float('nan'), float('nan'))
            out.append({'scenario': 'hairstyle', 'model': model, 'integrator': integ,
                        'dt': dt, 'cost_s_per_sim_s': cost / duration, 'rms_error_m': rms,
                        'final_error_m': final, 'stable': ok})
    return out


def run(quick=False, plot_dir=None):
    """Run the three scenarios; return the records (and write one plot per scenario)."""
    dts = DT_QUICK if quick else DT_FULL
    records = pendulum_records(dts, 0.5 if quick else 2.0)
    records += chain_records(dts, 0.5 if quick else 2.0)
    records += hairstyle_records(dts, 0.2 if quick else 2.0,
                                 ref_dt=1.0 / 4000 if quick else 1.0 / 24000)
    if plot_dir:
        plot(records, plot_dir)
    return records


def plot(records, plot_dir):
    """Write a log-log work-precision plot per scenario."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    paths_out = []
    for scen in ('pendulum', 'chain', 'hairstyle'):
        fig, ax = plt.subplots(figsize=(5, 4))
        for (model, integ), marker in zip(VARIANTS, 'os^'):
            rs = [r for r in records if r['scenario'] == scen and r['model'] == model
                  and r['integrator'] == integ and r['stable'] and r['rms_error_m']
                  and r['rms_error_m'] > 0]
            if rs:
                ax.loglog([r['cost_s_per_sim_s'] for r in rs], [r['rms_error_m'] for r in rs],
                          marker=marker, label=model if model == 'articulated' else
                          '%s, %s' % (model, integ))
                for r in rs:
                    xy = (r['cost_s_per_sim_s'], r['rms_error_m'])
                    ax.annotate('1/%d' % round(1 / r['dt']), xy, fontsize=6)
        ax.axhline(1e-3, color='0.6', lw=0.8, ls='--')
        ax.set_xlabel('CPU s per simulated s')
        ax.set_ylabel('RMS vertex error (m)')
        ax.set_title('work-precision: %s' % scen)
        ax.legend()
        paths_out.append(save_figure(fig, '%s/accuracy_%s.png' % (plot_dir, scen)))
        plt.close(fig)
    return paths_out
