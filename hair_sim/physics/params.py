"""
Physical parameters of the solver: SI defaults, where each comes from, and their ranges.

A simulated strand stands for half a strip, a bundle of `hairs_per_strand` real hairs.
"""

from dataclasses import asdict, dataclass, fields
import math
import numbers

import numpy as np

from hair_sim.physics.inputs import real_number, shown
from hair_sim.physics.motion import TELEPORT_ANGLE, TELEPORT_DISTANCE

# name: (low, high) inclusive ranges; the node declares the same ranges to ROS.
RANGES = {
    'hair_density': (100.0, 5000.0),
    'hair_radius': (5e-6, 2e-4),
    'hairs_per_strand': (1.0, 20000.0),
    'youngs_modulus': (1e6, 2e10),
    'stiffness_scale': (0.05, 100.0),   # hair always has bending stiffness; limp hair
    #                                     (below ~0.05) chatters on contact at 1/60 s
    'damping': (0.0, 200.0),
    'gravity': (0.0, 50.0),
    'drag_coefficient': (0.0, 5.0),
    'drag_width': (0.0, 0.1),
    'air_density': (0.0, 5.0),
    'collision_stiffness': (0.0, 1000.0),
    'collision_damping': (0.0, 10.0),
    'neighbor_stiffness': (0.0, 100.0),
    'wall_stiffness': (0.0, 100.0),
    'wall_distance': (0.0, 0.05),
    'scalp_stiffness': (0.0, 100.0),
    'scalp_spring_reach': (0.0, 0.2),
    'max_wind_speed': (0.0, 100.0),
    'sleep_tolerance': (0.0, 0.01),
    'sleep_delay': (0.0, 10.0),
    'max_head_speed': (0.1, 1000.0),
    'max_head_angular_speed': (0.1, 1000.0),
    'max_head_acceleration': (1.0, 10000.0),
    'motion_smoothing': (0.0, 1.0),
    'head_deadband': (0.0, 0.05),
    'head_turn_deadband': (0.0, 0.2),
    'clock_jump_back': (0.001, 86400.0),
    'root_stiffness_scale': (0.0, 1e9),
    'shape_stiffness': (0.0, 1.0),     # 0.1 already holds the style within 2 cm in gusts
    'air_damping': (0.0, 100.0),
    'contact_friction': (0.0, 2.0),
}
# the shape_stiffness suggested for styled hair on the articulated model (README): every
# strand of every shipped style back after the demo's gusts (hair_sim_bench style; 0.003
# and 0.01 left 2-3 strands of thesis_long, side_swept_long and thesis_short off)
STYLED_SHAPE_STIFFNESS = 0.03
INTEGRATORS = ('explicit', 'implicit')
MODELS = ('anjyo', 'articulated')
# name: what it means, in one line (the node's parameter descriptors and --help say it)
DESCRIPTIONS = {
    'hair_density': 'density of a hair fibre (kg/m^3)',
    'hair_radius': 'radius of a hair fibre (m)',
    'hairs_per_strand': 'real hairs one simulated strand stands for (its mass and stiffness)',
    'youngs_modulus': 'Young\'s modulus of a hair fibre (Pa)',
    'stiffness_scale': 'bending stiffness, times the estimate from youngs_modulus and '
                       'hair_radius (raise it for gelled or styled hair)',
    'model': 'strand model: anjyo (the thesis, eqs. 1-6) or articulated (an exact chain of '
             'rods; stable at sim_rate 60)',
    'root_stiffness_scale': 'the follicle joint\'s stiffness, times the others\' '
                            '(articulated model; very large: clamped)',
    'shape_stiffness': 'pull of every segment towards its modeled direction under the head '
                       '(articulated model; N m/rad per m of strand; 0: exact physics)',
    'damping': 'damping rate of the strands\' swing (1/s)',
    'air_damping': 'drag against still air, -air_damping m v on each segment (1/s; apart from '
                   'the wind\'s drag)',
    'gravity': 'gravity along -z of the world frame (m/s^2)',
    'gravity_compensation': 'hold the modeled style under gravity with the head upright '
                            '(false: it sags first)',
    'drag_coefficient': 'wind drag coefficient of a strand (a cylinder: about 1.2)',
    'drag_width': 'width of a strand\'s bundle the wind acts on (m)',
    'air_density': 'density of the air (kg/m^3)',
    'collision_stiffness': 'stiffness of the reaction constraint, eq. 8 (N/m per m of strand)',
    'collision_damping': 'damping of the reaction constraint, eq. 8 (N s/m per m of strand)',
    'contact_friction': 'Coulomb friction between hair and the head\'s spheres (articulated '
                        'model; 0: frictionless)',
    'neighbor_stiffness': 'springs between facing strands of neighbouring strips, type 1 of '
                          'thesis 5.2 (N/m per m)',
    'wall_stiffness': 'springs from a vertex to its neighbour\'s wall, type 2 of thesis 5.2 '
                      '(N/m per m)',
    'wall_distance': 'type 2 springs act within this distance of the neighbour\'s wall (m)',
    'scalp_stiffness': 'springs from a vertex to its scalp projection, type 3 of thesis 5.2 '
                       '(N/m per m)',
    'scalp_spring_reach': 'type 3 springs hold vertices resting within this of the scalp (m)',
    'inter_strip': 'the springs between strips of thesis 5.2 on or off (fig. 5.1)',
    'collisions': 'collisions with the head\'s and body\'s spheres on or off',
    'integrator': 'anjyo model\'s integrator: explicit (thesis eq. 6) or implicit',
    'max_wind_speed': 'wind above this is clamped along its direction (m/s)',
    'max_head_speed': 'a head jumping over %g m faster than this is a teleport: the hair '
                      'is carried with it (m/s)' % TELEPORT_DISTANCE,
    'max_head_angular_speed': 'a head turning over %g rad faster than this is a teleport: '
                              'the hair is carried with it (rad/s)' % TELEPORT_ANGLE,
    'max_head_acceleration': 'head accelerations are clamped to this (m/s^2)',
    'motion_smoothing': 'low-pass time constant of the head\'s velocity (s): holds a '
                        'tracker\'s noise out, and lags the head the hair feels by about '
                        'as long; 0 for poses without noise',
    'head_deadband': 'a tracker\'s noise: the head stays put until a pose is this far from '
                     'it, then trails the pose by this much (m); 0: off',
    'head_turn_deadband': 'the same for the head\'s turn: a pose turned less than this from '
                          'the head leaves it as it is, then it trails by this much (rad); '
                          '0: off',
    'clock_jump_back': 'a pose stamped this much before the last one re-anchors the clock; a '
                       'smaller step back is dropped (s)',
    'sleep_tolerance': 'sleep when no vertex moves more than this for sleep_delay (m)',
    'sleep_delay': 'sleep when no vertex moves more than sleep_tolerance for this long (s)',
}


@dataclass
class PhysicsParams:
    """Solver parameters; every value is SI. The sources are in the comments."""

    # Material of one strand (a bundle of hairs), after Robbins, "Chemical and Physical
    # Behavior of Human Hair": keratin density ~1300 kg/m^3, fibre radius 30-50 um, Young's
    # modulus 2-5 GPa. 500 hairs per strand: a 46-strip style of 92 strands then holds about
    # 46 000 hairs, half a real head; the other half is what the U-shape texture suggests.
    hair_density: float = 1300.0        # kg/m^3
    hair_radius: float = 35e-6          # m
    hairs_per_strand: float = 500.0
    youngs_modulus: float = 4e9         # Pa
    # Hinge spring of eq. 3: k = stiffness_scale * E * I_area * hairs / l (a cantilever of
    # unbonded fibres); 1.0 is that estimate, raise it for gelled or styled hair.
    stiffness_scale: float = 1.0
    # Which strand model: 'anjyo' (the thesis, eqs. 1-6: each segment swings about its
    # start with its own inertia) or 'articulated' (an exact chain of rods on ball joints).
    model: str = 'anjyo'
    # The first joint's (the follicle's) stiffness is this times the others'; articulated
    # model only (very large: clamped).
    root_stiffness_scale: float = 1.0
    # Articulated model only: a couple -shape_stiffness * l * e on every segment, e the
    # rotation from its modeled direction under the head to its direction (N m/rad per
    # metre of strand). The chain's own springs act between neighbours, so a lock blown
    # over the crown can rest there; this pulls each segment back to the style, as the
    # thesis' absolute hinges (eq. 3) and TressFX's global shape constraints do. 0, the
    # default, is the exact chain; STYLED_SHAPE_STIFFNESS brings the shipped styles back
    # after the demo's gusts (README, hair_sim_bench style).
    shape_stiffness: float = 0.0
    # gamma_i / I_i of eq. 1 (1/s). 12/s gives a damping ratio of about 0.12 at the default
    # hinge frequency: hair swings a few times and settles within about 1 s. The
    # articulated model spends a fifth of it on joint dampers (d = 0.2 damping times the
    # inertia of everything beyond the joint about it) and a third on drag against still
    # air (like air_damping, on top of it): joint dampers alone leave a long strand
    # creeping for seconds (see solvers/articulated.py).
    damping: float = 12.0
    # A force -air_damping * m * v on each segment's centre, relative to still air (1/s);
    # separate from wind drag.
    air_damping: float = 0.0
    gravity: float = 9.81               # m/s^2, along -z of the world frame
    # Turn the hinges' rest directions so the modeled style is the equilibrium under
    # gravity with the head upright (styled hair holds its shape); off: it sags first.
    gravity_compensation: bool = True
    # Wind drag on a segment: 0.5 * rho_air * Cd * width * l * |v_perp| v_perp. Cd ~1.2 for
    # a cylinder at the Reynolds numbers of hair; width is the bundle's effective width.
    drag_coefficient: float = 1.2
    drag_width: float = 0.006           # m
    air_density: float = 1.2            # kg/m^3
    # Reaction constraint of eq. 8: k (N/m) and c (N s/m) per metre of strand, so that, like
    # the mass, they scale with segment length. Kept soft enough for the explicit force
    # term at 60 Hz; a position guard (see kernels) stops deep penetration.
    collision_stiffness: float = 1.5
    collision_damping: float = 0.06
    # Coulomb friction between hair and the head's and body's spheres (articulated model
    # only; the thesis model has none): a contact point stops sliding while the tangential
    # impulse needed is at most this times the normal one.
    contact_friction: float = 0.0
    # Springs of thesis 5.2 (eq. 11), N/m per metre of strand: type 1 between facing
    # strands of neighbouring strips, type 2 from a vertex to its neighbour's projected
    # wall (inserted only within wall_distance), type 3 from a vertex to its own scalp
    # projection (thickness), for vertices whose rest distance to the scalp is below
    # scalp_spring_reach. Their frequency sqrt(3 k / lambda) stays below 70 rad/s.
    neighbor_stiffness: float = 0.3
    wall_stiffness: float = 1.5
    wall_distance: float = 0.002        # m
    scalp_stiffness: float = 0.6
    scalp_spring_reach: float = 0.03    # m
    inter_strip: bool = True            # thesis fig. 5.1: inter-strip handling on/off
    collisions: bool = True
    integrator: str = 'implicit'        # 'explicit' (thesis eq. 6) or 'implicit'
    # Inputs beyond these are clamped (wind) or treated as a teleport (head).
    max_wind_speed: float = 40.0        # m/s
    max_head_speed: float = 10.0        # m/s
    max_head_angular_speed: float = 40.0  # rad/s
    max_head_acceleration: float = 300.0  # m/s^2 (about 30 g)
    motion_smoothing: float = 0.02      # s, low-pass time constant of head velocity
    # A tracker's noise, held out (0: off): a pose within head_deadband (m) of the head and
    # turned less than head_turn_deadband (rad) from it leaves it where it is; one beyond
    # moves it by the excess only (a backlash), so the head trails a real motion by these.
    head_deadband: float = 0.0
    head_turn_deadband: float = 0.0
    # A pose stamped more than this (s) before the last one re-anchors the clock (a looping
    # bag, a restarted tracker); a smaller step back is an out-of-order pose and dropped.
    clock_jump_back: float = 0.5
    # Event-triggered animation (thesis 4.1): sleep when, with steady inputs, no vertex has
    # moved more than sleep_tolerance (m) for sleep_delay seconds.
    sleep_tolerance: float = 0.0005
    sleep_delay: float = 0.3

    def __post_init__(self):
        # Every number is kept as a Python float and every flag as a bool, whatever kind the
        # caller passed (an int, a numpy scalar): the kernels are compiled for floats. An
        # int reached them as it came, and numba compiled the kernels again for it (11 s
        # for contact_friction=1 on the articulated model) or failed to
        # (max_head_acceleration=300: a TypingError from the step, after the constructor
        # had accepted it), while numpy scalars were refused as "not a number".
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in RANGES and _is_number(v):
                setattr(self, f.name, real_number(v, f.name))   # (past float's range: inf)
            elif f.type in ('bool', bool) and isinstance(v, np.bool_):
                setattr(self, f.name, bool(v))

    def validate(self):
        """Raise ValueError naming the first parameter that is out of range or mistyped."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in RANGES:
                lo, hi = RANGES[f.name]
                if not isinstance(v, float):
                    raise ValueError('%s must be a number, not %s' % (f.name, shown(v)))
                if not (math.isfinite(v) and lo <= v <= hi):
                    raise ValueError('%s = %r is outside [%g, %g]' % (f.name, v, lo, hi))
            elif f.type in ('bool', bool) and not isinstance(v, bool):
                raise ValueError('%s must be true or false, not %s' % (f.name, shown(v)))
        if self.model not in MODELS:
            raise ValueError('model must be one of %s, not %s'
                             % (', '.join(MODELS), shown(self.model)))
        if self.integrator not in INTEGRATORS:
            raise ValueError('integrator must be one of %s, not %s'
                             % (', '.join(INTEGRATORS), shown(self.integrator)))
        return self

    def replaced(self, **changes):
        """Return a validated copy with `changes` applied; unknown names raise ValueError."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ValueError('unknown parameter(s): %s' % ', '.join(sorted(unknown)))
        d = asdict(self)
        d.update(changes)
        return PhysicsParams(**d).validate()

    @property
    def linear_density(self):
        """Return the mass per metre of one strand (kg/m)."""
        return self.hairs_per_strand * math.pi * self.hair_radius ** 2 * self.hair_density

    @property
    def bundle_radius(self):
        """Return the radius (m) of a strand's bundle of fibres packed side by side."""
        return self.hair_radius * math.sqrt(self.hairs_per_strand)

    @property
    def bending_stiffness(self):
        """Return E * I of one strand (N m^2): unbonded fibres add up."""
        return (self.stiffness_scale * self.youngs_modulus * self.hairs_per_strand
                * math.pi * self.hair_radius ** 4 / 4.0)


def _is_number(v):
    """Return whether v is a real number (int, float, numpy scalar), not a flag."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
