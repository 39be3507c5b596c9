"""Checks of a style against its head, shared by the shipped and the moved styles."""

import numpy as np

from hair_sim import DEFAULT_DT, HairSimulator


def settled(style, **params):
    """Build a simulator of `style` and let it settle (sleep) under a still head."""
    sim = HairSimulator(style, **params)
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    while not sim.sleeping:
        sim.step(DEFAULT_DT)
        assert sim.time < 3.0, 'did not settle'
    return sim


def footprint_coverage(style, strips, reach=0.02):
    """Fraction of hair-region scalp samples with a strip point radially above within reach."""
    head = style.head
    n = 4000
    i = np.arange(n) + 0.5
    dirs = np.stack([np.cos(np.pi * (1 + 5 ** 0.5) * i) * np.sqrt(1 - (1 - 2 * i / n) ** 2),
                     np.sin(np.pi * (1 + 5 ** 0.5) * i) * np.sqrt(1 - (1 - 2 * i / n) ** 2),
                     1 - 2 * i / n], axis=1)
    centre = head.projection_sphere[:3]
    samples = head.nearest_on_scalp(centre + 0.3 * dirs)
    samples = samples[head.in_hair_region(samples) & (head.scalp_distance(samples) > -1e-9)]
    a, b = strips.rest[strips.strip_strands[:, 0]], strips.rest[strips.strip_strands[:, 1]]
    f = np.linspace(0, 1, 4)[:, None, None, None]
    a2 = np.concatenate([a, 0.5 * (a[:, 1:] + a[:, :-1])], axis=1)
    b2 = np.concatenate([b, 0.5 * (b[:, 1:] + b[:, :-1])], axis=1)
    dense = ((1 - f) * a2[None] + f * b2[None]).reshape(-1, 3)
    foot = head.nearest_on_scalp(dense)
    d2 = ((samples[:, None, :] - foot[None, :, :]) ** 2).sum(-1).min(axis=1)
    return float((d2 < reach ** 2).mean())
