"""
hair_sim_bench jitter: how a head tracker's noise shows in the hair, and what smoothing costs.

A tracker's poses of a still head scatter by its noise: here Gaussian, sigma mm in position
and sigma / 5 degrees about each axis (so 0.5 mm goes with 0.1 degrees, 2 mm with 0.4),
at 120 Hz, over 10 s (the first 2 s not counted). thesis_long, settled upright, under each
strand model at the default step, with the head's velocity low-passed over
`physics.motion_smoothing` seconds, and without or with the deadbands that hold a
tracker's noise out (`physics.head_deadband` and `head_turn_deadband`, here 5 sigma: 5
sigma mm and sigma degrees). Per run: how far the tips stray from where they rest
relative to the head (head frame: the hair moving on the head, which the head drawn under
the same noisy pose makes visible), and in the world (mean and 95th percentile), against
the world scatter of hair glued to the head (its rest tips carried by each noisy pose: the
tracker's own noise at the tips); the share of the steps the hair slept, and the CPU
seconds a simulated second took; and what the smoothing and the deadbands cost on a real
motion: how far the tips trail a 90 degree yaw in 0.3 s at its end (mean), with a clean
tracker, and how far short of the tracker's last pose the head then rests (degrees).
"""

import math
import time

import numpy as np
from scipy.spatial.transform import Rotation

from hair_sim import load_hairstyle, paths
from hair_sim.bench import style_keeping
from hair_sim.bench.common import progress
from hair_sim.bench.scenarios import drive, quarter_turn
from hair_sim.physics.motion import quat_to_matrix
from hair_sim.physics.simulator import DEFAULT_DT

STYLE = 'thesis_long'
MODELS = ('anjyo', 'articulated')
NOISE_MM = (0.5, 2.0)             # position sigma; rotation sigma is NOISE_MM / 5 degrees
SMOOTHING = (0.02, 0.05, 0.1, 0.2)   # s; 0.02 is PhysicsParams' default
TRACKER_HZ = 120.0
SECONDS = 10.0
UNCOUNTED = 2.0                   # s at the start, while the noise first stirs the hair


def deadbands(sigma_mm):
    """Return the (head_deadband m, head_turn_deadband rad) for a tracker's noise: 5 sigma."""
    return 5e-3 * sigma_mm, math.radians(sigma_mm)


def settled(style, model, smoothing, held=(0.0, 0.0)):
    """Return the simulator of the style at rest with the head upright at the origin, and t."""
    return style_keeping.settled(style, model, DEFAULT_DT, 0.0, style_keeping.UPRIGHT,
                                 motion_smoothing=smoothing, head_deadband=held[0],
                                 head_turn_deadband=held[1])


def noisy_poses(sigma_mm, n, seed=0):
    """Return n tracker poses of a still head: positions (n, 3) m and quaternions (n, 4)."""
    rng = np.random.default_rng(seed)
    positions = rng.normal(0.0, sigma_mm * 1e-3, (n, 3))
    turns = rng.normal(0.0, np.radians(sigma_mm / 5.0), (n, 3))
    return positions, Rotation.from_rotvec(turns).as_quat()


def scatter(sim, t, sigma_mm):
    """
    Feed the noisy poses from t on; return the tips' stray (head frame, world) and glued's.

    Each is (mean, 95th percentile), mm, over the counted poses, of the tips' distance from
    the rest tips. Then the share of the steps asleep and the CPU seconds the poses and steps
    took per simulated second.
    """
    rest = sim.strand_positions()[:, -1].copy()
    rest_on_head = sim.positions_in_head_frame()[:, -1].copy()
    positions, quats = noisy_poses(sigma_mm, int(SECONDS * TRACKER_HZ))
    period = 1.0 / TRACKER_HZ
    steps = max(1, int(round(period / DEFAULT_DT)))
    on_head, stray, glued = [], [], []
    asleep = 0
    cpu = 0.0
    for k in range(len(positions)):
        t += period
        start = time.process_time()
        sim.set_head_pose(t, positions[k], quats[k])
        for _ in range(steps):
            sim.step(period / steps)
            asleep += sim.sleeping
        cpu += time.process_time() - start
        if k * period < UNCOUNTED:
            continue
        on_head.append(np.linalg.norm(sim.positions_in_head_frame()[:, -1] - rest_on_head,
                                      axis=1))
        stray.append(np.linalg.norm(sim.strand_positions()[:, -1] - rest, axis=1))
        carried = rest @ quat_to_matrix(quats[k]).T + positions[k]
        glued.append(np.linalg.norm(carried - rest, axis=1))
    cpu /= SECONDS
    return tuple((float(d.mean()), float(np.percentile(d, 95)))
                 for d in (1e3 * np.concatenate(x) for x in (on_head, stray, glued))) + (
        asleep / (steps * len(positions)), cpu)


def turn_trail(style, model, smoothing, held):
    """
    Return how far the tips trail a 90 degree yaw in 0.3 s, and how far short the head ends.

    The trail is the tips' mean distance (mm) from their rest on the head at the turn's
    end; the head's shortfall is in degrees, once it has stopped.
    """
    sim, t = settled(style, model, smoothing, held)
    tips = sim.positions_in_head_frame()[:, -1].copy()
    drive(sim, quarter_turn(t), t, 0.3, DEFAULT_DT)
    trail = 1e3 * float(np.linalg.norm(sim.positions_in_head_frame()[:, -1] - tips,
                                       axis=1).mean())
    R, _ = sim.head_pose
    return trail, 90.0 - math.degrees(math.atan2(R[1, 0], R[0, 0]))


def run(quick=False):
    """Return one record per (model, noise, smoothing, deadbands off or on)."""
    style = load_hairstyle(paths.shipped_style(STYLE))
    noises = NOISE_MM[-1:] if quick else NOISE_MM
    smoothings = SMOOTHING[::3] if quick else SMOOTHING
    cases = [(m, n, s, False) for m in MODELS for n in noises for s in smoothings] + \
        [(m, n, SMOOTHING[0], True) for m in MODELS for n in noises]
    records = []
    for model, sigma, smoothing, holding in progress(cases, 'jitter'):
        held = deadbands(sigma) if holding else (0.0, 0.0)
        sim, t = settled(style, model, smoothing, held)
        on_head, world, glued, asleep, cpu = scatter(sim, t, sigma)
        trail, short = turn_trail(style, model, smoothing, held)
        records.append(dict(style=STYLE, model=model, noise_mm=sigma,
                            noise_deg=sigma / 5.0, tracker_hz=TRACKER_HZ,
                            motion_smoothing_s=smoothing, head_deadband_m=held[0],
                            head_turn_deadband_rad=held[1],
                            on_head_mm_mean=on_head[0], on_head_mm_p95=on_head[1],
                            world_mm_mean=world[0], world_mm_p95=world[1],
                            glued_world_mm_mean=glued[0], glued_world_mm_p95=glued[1],
                            asleep_share=asleep, cpu_s_per_s=cpu, turn_trail_mm=trail,
                            turn_short_deg=short))
    return records
