"""
hair_sim_bench style: whether a hairstyle keeps its look in a breeze, and comes back.

Every shipped style, each strand model at its steps (the thesis model at the default
1/240 s; the articulated model at 1/240 s and at one step per 60 Hz frame, exact and with
the shape springs the README suggests, STYLED_SHAPE_STIFFNESS), under the
demo's calm head motion and the gusts hair_sim_head_driver sends (1.5-4 m/s every 2 s,
calm on every third). Per run: how far the tips are from the style settled under the
same model (head frame) while the gusts blow, and how many strands rest more than 3 cm
from it once the wind has stopped and the head has been held upright for 10 s. What
keeping the style costs in motion: how far the tips trail a 90 degree yaw in 0.3 s, and
how far they hang over, under their own weight, with the head held tilted ear to shoulder.
"""

import numpy as np

from hair_sim import load_hairstyle, paths
from hair_sim.bench.common import progress
from hair_sim.bench.scenarios import (demo, demo_gust, drive, GUST_PERIOD, quarter_turn,
                                      quat_from_euler)
from hair_sim.physics.params import STYLED_SHAPE_STIFFNESS
from hair_sim.physics.simulator import DEFAULT_DT, HairSimulator

# (model, dt, shape_stiffness)
RUNS = (('anjyo', DEFAULT_DT, 0.0), ('articulated', DEFAULT_DT, 0.0),
        ('articulated', 1.0 / 60, 0.0), ('articulated', 1.0 / 60, STYLED_SHAPE_STIFFNESS))
OFF_STYLE = 0.03        # m: a strand whose tip rests farther than this is off its style
RIDING = 0.05           # m: a tip this far above its place is blown up
SETTLE_S = 5.0          # s the style gets to settle under the first pose, still air
UPRIGHT = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
TILTED = ([0.0, 0.0, 0.0], quat_from_euler(0.5 * np.pi, 0.0, 0.0))   # ear to shoulder


def settled(style, model, dt, shape_stiffness, pose, **params):
    """
    Return the simulator of the style at rest under a still pose (at most SETTLE_S), and t.

    params are further PhysicsParams of the simulator.
    """
    sim = HairSimulator(style, model=model, shape_stiffness=shape_stiffness, **params)
    t = 0.0
    sim.set_head_pose(t, *pose)
    while not sim.sleeping and t < SETTLE_S:
        t += dt
        sim.set_head_pose(t, *pose)
        sim.step(dt)
    return sim, t


def settled_tips(style, model, dt, shape_stiffness):
    """Return the tips (head frame) of the style settled under demo(0) in still air."""
    sim, _ = settled(style, model, dt, shape_stiffness, demo(0.0))
    return sim.positions_in_head_frame()[:, -1].copy()


def turn_lag(upright, t, dt, tips):
    """
    Return how far (m, mean) the tips trail a 90 degree yaw in 0.3 s, at its end.

    upright is the simulator settled with the head upright at t, tips its tips then (head
    frame); the turn moves it on.
    """
    drive(upright, quarter_turn(t), t, 0.3, dt)
    return float(np.linalg.norm(upright.positions_in_head_frame()[:, -1] - tips, axis=1).mean())


def tilt_hang(style, model, dt, shape_stiffness, tips):
    """
    Return how far (m, mean) the tips hang over when the head is held tilted 90 degrees.

    The style settled with the head rolled ear to shoulder against tips, its tips settled
    upright, both in the head frame: how much the hair falls towards the shoulder under
    its own weight.
    """
    tilted, _ = settled(style, model, dt, shape_stiffness, TILTED)
    return float(np.linalg.norm(tilted.positions_in_head_frame()[:, -1] - tips,
                                axis=1).mean())


def run_one(style, model, dt, gusty_s, still_s, shape_stiffness):
    """Return the record of one style and model: gusts for gusty_s, then still_s still."""
    tips0 = settled_tips(style, model, dt, shape_stiffness)
    sim = HairSimulator(style, model=model, shape_stiffness=shape_stiffness)
    sim.set_head_pose(0.0, *demo(0.0))
    t, gust, off, riding = 0.0, 0, [], []
    every, gust_every = int(round(0.5 / dt)), int(round(GUST_PERIOD / dt))
    for i in range(int(round(gusty_s / dt))):
        if i % gust_every == 0:
            gust += 1
            velocity, turbulence, seed = demo_gust(gust)
            sim.set_wind(velocity, turbulence=turbulence, seed=seed)
        t += dt
        sim.set_head_pose(t, *demo(t))
        sim.step(dt)
        if i % every == 0 and t > 2.0:
            tips = sim.positions_in_head_frame()[:, -1]
            off.append(float(np.linalg.norm(tips - tips0, axis=1).mean()))
            riding.append(float(np.mean(tips[:, 2] > tips0[:, 2] + RIDING)))
    sim.set_wind([0.0, 0.0, 0.0])
    upright = demo(0.0)
    for _ in range(int(round(still_s / dt))):
        t += dt
        sim.set_head_pose(t, *upright)
        sim.step(dt)
    rest = np.linalg.norm(sim.positions_in_head_frame()[:, -1] - tips0, axis=1)
    off = np.asarray(off)
    # what keeping the style costs in motion, from one upright settle
    upright, t_up = settled(style, model, dt, shape_stiffness, UPRIGHT)
    tips_up = upright.positions_in_head_frame()[:, -1].copy()
    hang = tilt_hang(style, model, dt, shape_stiffness, tips_up)
    return {'style': style.name, 'model': model, 'dt': dt, 'strands': int(len(rest)),
            'shape_stiffness': shape_stiffness,
            'gusty_s': gusty_s, 'tips_off_style_mean_m': float(off.mean()),
            'tips_off_style_p90_m': float(np.percentile(off, 90)),
            'tips_off_style_max_m': float(off.max()),
            'tips_riding_share': float(np.mean(riding)),
            'still_s': still_s, 'asleep_after': bool(sim.sleeping),
            'rest_off_style_mean_m': float(rest.mean()),
            'strands_off_style': int((rest > OFF_STYLE).sum()),
            'retried_steps': int(sim.counters['retried_steps']),
            'turn_lag_m': turn_lag(upright, t_up, dt, tips_up),
            'tilt_hang_m': hang}


def run(quick=False):
    """Measure every shipped style (thesis_long alone with --quick) with each of RUNS."""
    names = ['thesis_long'] if quick else paths.shipped_style_names()
    gusty_s, still_s = (6.0, 4.0) if quick else (24.0, 10.0)
    cases = [(name,) + run for name in names for run in RUNS]
    return [run_one(load_hairstyle(paths.shipped_style(name)), model, dt, gusty_s, still_s,
                    shape_stiffness)
            for name, model, dt, shape_stiffness in progress(cases, 'style')]
