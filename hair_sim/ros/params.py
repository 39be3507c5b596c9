"""Every node parameter: name, default, description and range (declared with descriptors)."""

from dataclasses import fields

from hair_sim.physics.params import DESCRIPTIONS, PhysicsParams, RANGES

PHYSICS = 'physics.'

# name: (default, description, (low, high) or None)
NODE_PARAMETERS = {
    'hairstyle': ('thesis_long', 'hairstyle to load: a name or a .yaml path relative to one '
                  'of hairstyle_dirs', None),
    'hairstyle_dirs': ([''], 'directories load/save (and a style\'s head file) may touch; '
                       '"" is the shipped config/hairstyles', None),
    'sim_rate': (240.0, 'solver steps per simulated second (Hz)', (30.0, 4000.0)),
    'frame_rate': (60.0, 'how often the solver catches up with the clock (Hz)', (5.0, 500.0)),
    'max_steps_per_frame': (16, 'steps at most per frame; time beyond is dropped', (1, 200)),
    'max_physics_share': (0.6, 'share of the wall time the solver may take on average; '
                          'simulated time beyond it is dropped (counted) so that the '
                          'outputs keep their rates', (0.05, 1.0)),
    'publish_rate': (30.0, 'rate of hair_mesh and hair_state, and of meshcat frames at most '
                     '(Hz)', (0.5, 240.0)),
    'marker_rate': (10.0, 'rate of hair_markers (Hz, at most publish_rate); a MarkerArray is '
                    'large', (0.5, 240.0)),
    'world_frame': ('world', 'frame of head poses, wind and world-frame output', None),
    'head_frame': ('', 'frame of this avatar\'s head (TF child, head-frame markers); "" takes '
                   'the head file\'s frame_id', None),
    'markers_in_head_frame': (False, 'hair_markers in head_frame (frame_locked; needs the '
                              'head in TF) instead of world_frame', None),
    'publish_tf': (True, 'publish world_frame -> head_frame on /tf from the pose stream '
                   '(when tf2_msgs is installed)', None),
    'interpolate_poses': (True, 'follow the head about one pose interval (at most 0.1 s) '
                          'behind its newest pose, so that it moves smoothly between a live '
                          'tracker\'s poses; false: at once, the head held at each newest '
                          'pose until the next lands (less latency, a head moving in steps)',
                          None),
    'use_viewpoint': (False, 'cull strips that cannot be seen from viewpoint', None),
    'viewpoint': ([0.8, 0.0, 0.0], 'eye position for culling, world frame (m)', None),
    'publish_markers': (True, 'publish hair_markers (MarkerArray)', None),
    'publish_mesh': (True, 'publish hair_mesh (HairMesh) and hair_mesh_topology', None),
    'publish_state': (True, 'publish hair_state (HairState)', None),
    'meshcat.enabled': (False, 'stream the hair to a meshcat viewer', None),
    'meshcat.rate': (20.0, 'meshcat frames per second', (0.5, 120.0)),
    'meshcat.zmq_url': ('', 'meshcat server to use, tcp://host:port; empty starts one', None),
    'meshcat.view': ('three_quarter', 'meshcat camera, 0.45 m from the head: three_quarter, '
                     'front, side or back', None),
    'meshcat.show_spheres': (False, 'draw the collision spheres instead of the head mesh '
                             '(for tuning collisions)', None),
}


def physics_parameters():
    """Return {'physics.<field>': (default, description, range)} for every PhysicsParams."""
    out = {}
    defaults = PhysicsParams()
    for f in fields(PhysicsParams):
        out[PHYSICS + f.name] = (getattr(defaults, f.name), DESCRIPTIONS[f.name],
                                 RANGES.get(f.name))
    return out


def all_parameters():
    """Return every parameter the node declares."""
    out = dict(NODE_PARAMETERS)
    out.update(physics_parameters())
    return out
