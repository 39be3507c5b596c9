"""Wind: a mean velocity plus deterministic, seeded turbulence (a sum of travelling modes)."""

import numpy as np

from hair_sim.physics.forces import WindField
from hair_sim.physics.inputs import integer, real_array, real_number

N_MODES = 8


def _fresh(a, shape):
    """Return a new, C-ordered, writeable float64 copy of `a`, of `shape`."""
    return np.array(a, dtype=np.float64, order='C', copy=True).reshape(shape)


class Wind:
    """Mean wind (m/s, world frame) and turbulence modes drawn from a seed."""

    def __init__(self):
        self.set((0.0, 0.0, 0.0), 0.0, 0)

    def set(self, velocity, turbulence=0.0, seed=0):
        """Set the mean velocity, turbulence intensity (>= 0) and seed of the gusts."""
        # all checked before anything is set: a bad seed left a new velocity behind
        v = real_array(velocity, 3, 'wind velocity')
        turbulence = real_number(turbulence, 'turbulence')
        seed = integer(seed, 'seed')
        if not (np.all(np.isfinite(v)) and np.isfinite(turbulence)) or turbulence < 0:
            raise ValueError('wind needs a finite velocity and a finite turbulence >= 0')
        self.velocity = v
        self.turbulence = turbulence
        self.seed = seed & 0xFFFFFFFF
        rng = np.random.default_rng(self.seed)
        d = rng.normal(size=(N_MODES, 3))
        self.mode_dir = d / np.linalg.norm(d, axis=1, keepdims=True)
        k = rng.normal(size=(N_MODES, 3))
        wavenumber = rng.uniform(2, 12, (N_MODES, 1))               # rad/m
        self.mode_k = k / np.linalg.norm(k, axis=1, keepdims=True) * wavenumber
        self.mode_w = 2 * np.pi * rng.uniform(0.3, 2.5, N_MODES)
        self.mode_phase = rng.uniform(0, 2 * np.pi, N_MODES)
        # each mode's amplitude so that the gusts' rms per axis is turbulence * |v|
        self.amplitude = turbulence * float(np.linalg.norm(v)) * np.sqrt(2.0 * 3.0 / N_MODES)
        # what the force kernel takes, built once per change, of the same types every time
        # (fresh C-ordered float64 arrays and a float): the simulator's compiled steps are
        # called with it without typing it again (HairSimulator.set_wind)
        self.field = WindField(velocity=_fresh(self.velocity, (3,)),
                               amplitude=float(self.amplitude),
                               mode_dir=_fresh(self.mode_dir, (N_MODES, 3)),
                               mode_k_by_axis=_fresh(self.mode_k.T, (3, N_MODES)),
                               mode_w=_fresh(self.mode_w, (N_MODES,)),
                               mode_phase=_fresh(self.mode_phase, (N_MODES,)),
                               scratch=np.zeros((2, N_MODES)))
        self._active = bool(np.any(self.velocity != 0.0))

    @property
    def active(self):
        """Return True when the wind exerts any force (a mean or gusts)."""
        return self._active

    @property
    def steady(self):
        """Return True when the wind does not change in time (no gusts)."""
        return self.amplitude == 0.0
