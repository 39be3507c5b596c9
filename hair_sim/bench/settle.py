"""
hair_sim_bench settle: every shipped style, at every step, comes to rest after abuse.

Per shipped style, solver step, wind and turbulence seed: 2 s of the stress bench's
violent head motion (`scenarios.violent`) in the wind, then the wind stops and the head
holds its last pose for up to 8 s. Each seed also starts the motion at its own phase
(PHASES): in still air the seed picks nothing else, and the four still-air runs of a
style and step were one run four times; where the motion stops decides which strands are
left balanced, and a single phase hid how long the slowest take (thesis_long at 1/60 s,
the motion advanced by 0, 0.13, ... 1.57 s: asleep 2.8-3.2 s after it stopped at four of
seven phases, 4.3 and 6.7 s at two, and at 0.89 s not within 10 s). A run settles when
the hair falls asleep (`HairSimulator.sleeping`: no vertex left a sleep_tolerance ball for
sleep_delay) within those 8 s. Each run records when it slept, or the largest vertex move
of its last step (a strand still swinging shows there), whether it diverged (the
simulator put the hair back at rest: not asleep), and whether the model's own stability
check (`stability_problem`) accepts the step: a step it accepts is a promise that the
hair settles. The stress bench abuses one style in many ways; this abuses every style in
one way, at every step a user may pick.
"""

import numpy as np

from hair_sim import load_hairstyle, paths
from hair_sim.bench.common import progress
from hair_sim.bench.scenarios import drive, violent
from hair_sim.physics import SimulationDiverged
from hair_sim.physics.simulator import HairSimulator, stability_problem

STEPS = (1 / 60, 1 / 120, 1 / 240)
WINDS = (0.0, 10.0, 30.0)          # m/s along +x, turbulence 1
SEEDS = (1, 2, 3, 4)               # the wind's turbulence seeds
PHASES = (0.0, 0.37, 0.89, 1.21)   # s the violent motion is advanced by, one per seed
MOTION_S = 2.0                     # s of violent motion in the wind
WINDOW_S = 8.0                     # s the hair has to fall asleep in, head still, no wind


def run_one(style, model, dt, wind, seed, phase=0.0, shape_stiffness=0.0):
    """Return the record of one run (see the module text); phase advances the motion (s)."""
    sim = HairSimulator(style, model=model, shape_stiffness=shape_stiffness)
    promised = stability_problem(sim.params, sim, dt) is None
    sim.set_wind([wind, 0.0, 0.0], turbulence=1.0, seed=seed)
    record = {'style': style.name, 'model': model, 'shape_stiffness': shape_stiffness,
              'dt': dt, 'wind_mps': wind, 'seed': seed,
              'phase_s': phase, 'promised': promised, 'diverged': False,
              'slept_after_s': None, 'last_step_max_move_m': None}

    def motion(t):
        return violent(t + phase)
    try:
        t = drive(sim, motion, 0.0, MOTION_S, dt)
        sim.set_wind([0.0, 0.0, 0.0])
        hold = motion(t)
        last_move = 0.0
        for i in range(int(round(WINDOW_S / dt))):
            before = sim.pos.copy()
            sim.set_head_pose(t + (i + 1) * dt, *hold)
            sim.step(dt)
            if sim.sleeping:
                record['slept_after_s'] = (i + 1) * dt
                last_move = 0.0
                break
            last_move = float(np.linalg.norm(sim.pos - before, axis=2).max())
        record['last_step_max_move_m'] = last_move
    except SimulationDiverged:               # (the simulator put the hair back at rest)
        record['diverged'] = True
    return record


def summary(runs):
    """Return one row per style and step: runs, not asleep (diverged among them), worst move."""
    rows = []
    for style in dict.fromkeys(r['style'] for r in runs):
        for dt in dict.fromkeys(r['dt'] for r in runs):
            cell = [r for r in runs if r['style'] == style and r['dt'] == dt]
            if not cell:
                continue
            awake = [r for r in cell if r['slept_after_s'] is None]
            slept = [r['slept_after_s'] for r in cell if r['slept_after_s'] is not None]
            rows.append({'style': style, 'model': cell[0]['model'], 'dt': dt,
                         'shape_stiffness': cell[0].get('shape_stiffness', 0.0),
                         'promised': all(r['promised'] for r in cell), 'runs': len(cell),
                         'not_asleep': len(awake),
                         'diverged': sum(bool(r.get('diverged')) for r in cell),
                         'slowest_sleep_s': max(slept) if slept else None,
                         'worst_last_step_move_m': max(
                             (r['last_step_max_move_m'] or 0.0 for r in awake), default=0.0)})
    return rows


def run(quick=False, model='anjyo', shape_stiffness=0.0):
    """
    Run every shipped style at every step, wind and seed; return {'runs', 'summary'}.

    quick: the 30 m/s wind and seed 1 (phase 0) only (a run per style and step).
    shape_stiffness: the articulated model's shape springs.
    """
    names = paths.shipped_style_names()
    winds, seeds = ((30.0,), SEEDS[:1]) if quick else (WINDS, SEEDS)
    jobs = [(name, dt, wind, seed) for name in names for dt in STEPS for wind in winds
            for seed in seeds]
    styles = {name: load_hairstyle(paths.shipped_style(name)) for name in names}
    runs = [run_one(styles[name], model, dt, wind, seed, PHASES[SEEDS.index(seed)],
                    shape_stiffness)
            for name, dt, wind, seed in progress(jobs, 'settle %s' % model)]
    return {'runs': runs, 'summary': summary(runs)}
