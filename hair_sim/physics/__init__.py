"""Strand physics: Anjyo's angular-moment model with collisions and springs (thesis 4-5)."""

from hair_sim.physics.params import PhysicsParams
from hair_sim.physics.simulator import DEFAULT_DT, HairSimulator, stability_problem

__all__ = ['DEFAULT_DT', 'HairSimulator', 'PhysicsParams', 'stability_problem']
