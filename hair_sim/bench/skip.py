"""
hair_sim_bench skip: what a scene does not need must cost (almost) nothing.

The cost of one frame (the default substeps and the U-shape mesh) with each feature on and
off: sleeping against awake, culling from a front viewpoint against none, wind, inter-strip
springs, and the collision broad phase (far spheres skipped against every sphere tested).
"""

import time

import numpy as np

from hair_sim import load_hairstyle, paths
from hair_sim.bench.common import progress
from hair_sim.bench.scenarios import demo
from hair_sim.physics.simulator import DEFAULT_DT, HairSimulator
from hair_sim.physics.simulator import SUBSTEPS_PER_60HZ_FRAME as SUBSTEPS
from hair_sim.render import HairRenderer

FRONT = [0.8, 0.0, 0.0]


def _frame_ms(sim, frames, moving=True, viewpoint=None):
    """Median ms of frames: SUBSTEPS steps (with the demo motion if moving) and a mesh."""
    renderer = HairRenderer.for_simulator(sim)
    times = []
    for f in range(frames + 2):
        t0 = time.perf_counter()
        for _ in range(SUBSTEPS):
            t = sim.time + DEFAULT_DT
            if moving:
                sim.set_head_pose(t, *demo(t))
            sim.step(DEFAULT_DT)
        renderer.mesh_of(sim, viewpoint)
        if f >= 2:
            times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def _sim(style, **params):
    sim = HairSimulator(style, **params)
    sim.set_head_pose(0.0, *demo(0.0))
    return sim


def feature_records(style, frames):
    """Return on/off frame costs of every skippable feature on one style."""
    out = []
    name = '%s (%d strips)' % (style.name, style.n_strips)

    def rec(feature, work_ms, skipped_ms, note):
        """work_ms: everything computed; skipped_ms: what the scene does not need skipped."""
        out.append({'style': name, 'feature': feature, 'work_ms': work_ms,
                    'skipped_ms': skipped_ms,
                    'saving': 1.0 - skipped_ms / work_ms if work_ms else None, 'note': note})

    awake = _sim(style)
    awake_ms = _frame_ms(awake, frames)
    asleep = _sim(style)
    while not asleep.sleeping and asleep.time < 5.0:
        asleep.step(DEFAULT_DT)
    asleep_ms = _frame_ms(asleep, frames, moving=False)
    rec('sleeping (a whole frame: steps and mesh)', awake_ms, asleep_ms,
        'asleep, a step compares a few inputs and the mesh of the unchanged state is reused'
        + ('' if asleep.sleeping else ' (did not fall asleep!)'))
    windy = _sim(style)
    windy.set_wind([3.0, 1.0, 0.0], turbulence=0.5, seed=3)
    rec('wind off', _frame_ms(windy, frames), awake_ms, 'no drag evaluated')
    rec('inter-strip springs off', awake_ms,
        _frame_ms(_sim(style, inter_strip=False), frames), 'the thesis fig. 5.1c')
    no_broad = _sim(style)
    no_broad.broad_phase = False
    rec('collision broad phase', _frame_ms(no_broad, frames), awake_ms,
        'spheres a strand cannot reach are not tested')
    return out


def _mesh_ms(sim, frames, viewpoint=None):
    """Mean ms of building the mesh afresh (the state cache is bypassed)."""
    r = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    return _timed_ms(lambda: r.mesh(sim.pos, R, p, viewpoint), frames)


def _moving_frames(style, count):
    """Return `count` frames (strand positions, R, p) of the demo motion, one per mesh."""
    sim = _sim(style)
    frames = []
    while len(frames) < count:
        for _ in range(SUBSTEPS):
            t = sim.time + DEFAULT_DT
            sim.set_head_pose(t, *demo(t))
            sim.step(DEFAULT_DT)
        R, p = sim.head_pose
        frames.append((sim.pos.copy(), R.copy(), p.copy()))
    return frames


def _moving_mesh_ms(r, frames, viewpoint=None):
    """Mean ms of building the meshes of recorded frames in order, one renderer."""
    t0 = time.perf_counter()
    for pos, R, p in frames:
        r.mesh(pos, R, p, viewpoint)
    return 1e3 * (time.perf_counter() - t0) / len(frames)


def culling_record(style, frames, rounds=7):
    """
    Return the cost of the mesh seen from the front, culled (test included) and whole.

    The style settles under the demo's first pose (asleep, so every repeat meshes the same
    state); the visibility test alone is reported in the note. Whole and culled are timed
    in turns, `rounds` times each, so that a drift of the machine's speed falls on both:
    the saving is the median of the rounds' savings, and their range is reported with it.
    Culling remembers which strips' proofs failed (they are drawn unproven for a few
    frames), so the same is measured on moving hair too: 2 s of the demo motion, one mesh
    a 60 Hz frame, meshed in order ('saving_moving').
    """
    sim = _sim(style)
    while not sim.sleeping and sim.time < 5.0:
        sim.step(DEFAULT_DT)
    r = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    test_ms = _timed_ms(lambda: r.visible(sim.pos, R, p, FRONT), frames)
    whole, culled = [], []
    for _ in range(rounds):
        whole.append(_mesh_ms(sim, frames))
        culled.append(_mesh_ms(sim, frames, FRONT))
    savings = [1.0 - c / w for w, c in zip(whole, culled)]
    drawn = len(r.visible(sim.pos, R, p, FRONT))
    motion = _moving_frames(style, 120)
    moving = HairRenderer.for_simulator(sim)
    _moving_mesh_ms(moving, motion, FRONT)
    moving_savings = []
    for _ in range(rounds):
        w = _moving_mesh_ms(moving, motion)
        moving_savings.append(1.0 - _moving_mesh_ms(moving, motion, FRONT) / w)
    return {'style': '%s (%d strips)' % (style.name, style.n_strips),
            'feature': 'culling from the front (building the mesh)',
            'work_ms': float(np.median(whole)), 'skipped_ms': float(np.median(culled)),
            'saving': float(np.median(savings)),
            'saving_range': [float(min(savings)), float(max(savings))], 'rounds': rounds,
            'saving_moving': float(np.median(moving_savings)),
            'saving_moving_range': [float(min(moving_savings)), float(max(moving_savings))],
            'visibility_test_ms': test_ms, 'strips_drawn': drawn,
            'note': 'strips drawn %d of %d; the visibility test alone %.3f ms; saving %+.1f '
                    'to %+.1f %% over %d rounds (moving hair %+.1f to %+.1f %%); the culled '
                    'ones are not sent to meshcat either'
                    % (drawn, style.n_strips, test_ms, 100 * min(savings),
                       100 * max(savings), rounds, 100 * min(moving_savings),
                       100 * max(moving_savings))}


def _timed_ms(fn, frames):
    fn()
    t0 = time.perf_counter()
    for _ in range(frames):
        fn()
    return 1e3 * (time.perf_counter() - t0) / frames


def run(quick=False, plot_dir=None):
    """
    Measure the sample style and the 1000-strip style (200 strips with --quick).

    Culling is measured on every shipped style and on the refined one.
    """
    base = load_hairstyle(paths.shipped_style('thesis_long'))
    styles = [base, base.with_strip_count(200 if quick else 1000)]
    frames = 5 if quick else 30
    records = []
    for style in progress(styles, 'skip'):
        records += feature_records(style, frames)
    for style in progress([load_hairstyle(paths.shipped_style(n))
                           for n in paths.shipped_style_names()] +
                          [styles[1]], 'culling'):
        records.append(culling_record(style, 10 * frames))
    return records
