"""hair_sim: real-time strip-based hair with U-shape volume (Liang 2003) for ROS 2."""

# first: where numba may cache the kernels, before any is defined (see kernels.py)
from hair_sim import kernels  # noqa: F401,I100

from hair_sim.modeling import (build_strips, HairstyleError, load_hairstyle, load_head,
                               save_hairstyle)
from hair_sim.physics import DEFAULT_DT, HairSimulator, PhysicsParams

__version__ = '0.1.0'

__all__ = ['DEFAULT_DT', 'HairSimulator', 'HairstyleError', 'PhysicsParams', 'build_strips',
           'load_hairstyle', 'load_head', 'save_hairstyle']
