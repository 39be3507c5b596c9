"""Strand physics: the shared forces, two strand models and the HairSimulator driver."""

from hair_sim.physics.params import MODELS, PhysicsParams
from hair_sim.physics.simulator import (DEFAULT_DT, HairSimulator, SimulationDiverged,
                                        stability_problem)

__all__ = ['DEFAULT_DT', 'HairSimulator', 'MODELS', 'PhysicsParams', 'SimulationDiverged',
           'stability_problem']
