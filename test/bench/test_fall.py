"""
The bending energy that hair_sim_bench fall gives MuJoCo is the solver's.

The bench runs the stress gale's late strands in MuJoCo with couples from its own copy of
the chain's bending energy (fall.chain_energy, written from the energy's definition). That
copy must be the solver's energy, or MuJoCo would run another chain.
"""

import numpy as np
import pytest

from hair_sim import load_hairstyle, paths
from hair_sim.bench import fall
from hair_sim.bench.scenarios import violent
from hair_sim.physics.simulator import HairSimulator


@pytest.fixture(scope='module')
def tossed():
    """thesis_long (articulated) after 0.6 s of violent motion in the 30 m/s gale."""
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')),
                        model='articulated')
    sim.set_wind([30.0, 0.0, 0.0], turbulence=1.0, seed=1)
    dt = 1.0 / 240
    for i in range(144):
        sim.set_head_pose((i + 1) * dt, *violent((i + 1) * dt))
        sim.step(dt)
    return sim


def test_the_bench_chain_energy_is_the_solvers_bending_energy(tossed):
    """Summed over the strands, chain_energy equals the solver's potential_energy."""
    sim = tossed
    solver = sim.solver
    R_head = np.ascontiguousarray(sim.head_pose[0], dtype=float)
    ours = sum(fall.chain_energy(np.ascontiguousarray(solver.R[s, :, :, 2]), R_head,
                                 solver.rest_rel[s], solver.offset[s], solver.k[s])
               for s in range(len(solver.R)))
    theirs = solver.potential_energy(sim)
    assert theirs > 0.0
    # some joints are bent past a right angle, where the preload's weight changes
    parents = np.concatenate([np.broadcast_to(R_head, solver.R[:, :1].shape), solver.R[:, :-1]],
                             axis=1)
    axis_at_rest = np.einsum('sikj,sik->sij', parents @ solver.rest_rel, solver.R[..., :, 2])
    assert (axis_at_rest[..., 2] < 0.0).sum() >= 10
    # the state is far from rest, so the two can only agree if the definitions do
    rest = sum(fall.chain_energy(np.ascontiguousarray((R_head @ solver.modeled[s])[:, :, 2]),
                                 R_head, solver.rest_rel[s], solver.offset[s], solver.k[s])
               for s in range(len(solver.R)))
    assert abs(ours - rest) > 0.1 * theirs
    assert ours == pytest.approx(theirs, rel=1e-9)


def test_the_couples_are_the_energys_rate_under_a_turn(tossed):
    """Turning rod i by a small phi changes the energy by -couple_i . phi (first order)."""
    sim = tossed
    solver = sim.solver
    R_head = np.ascontiguousarray(sim.head_pose[0], dtype=float)
    rng = np.random.default_rng(3)
    for s in rng.choice(len(solver.R), 5, replace=False):
        axes = np.ascontiguousarray(solver.R[s, :, :, 2])
        args = (R_head, solver.rest_rel[s], solver.offset[s], solver.k[s])
        couples = np.zeros_like(axes)
        fall.chain_spring_couples(axes, *args, couples)
        for i in range(len(axes)):
            phi = 1e-6 * rng.normal(size=3)
            turned = axes.copy()
            turned[i] = axes[i] + np.cross(phi, axes[i])
            turned[i] /= np.linalg.norm(turned[i])
            change = fall.chain_energy(turned, *args) - fall.chain_energy(axes, *args)
            scale = np.linalg.norm(couples[i]) * np.linalg.norm(phi)
            assert change == pytest.approx(-couples[i] @ phi, abs=1e-3 * scale)
