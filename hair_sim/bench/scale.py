"""
hair_sim_bench scale: cost per frame against the number of strips (thesis table 5.1).

Styles of 20 .. 2000 strips are the sample style refined to that many strips (physics
LOD), each run with both strand models. Per row: simulated and rendered vertices, physics
step, frame (tessellation + U-shape), the hair_mesh message (vertices only; the topology
goes once per style), marker bytes and meshcat encoding in ms, message sizes before and
after the topology split, and end-to-end frames per second beside the thesis' frames per
second. Both models run at the default 4 solver steps per 60 Hz frame (`sim_rate` 240);
the articulated model also at one step per frame (`sim_rate` 60), where it is stable by
design and takes its own substeps where a segment would turn too far.
"""

import time

import numpy as np

from hair_sim import load_hairstyle, paths
from hair_sim.bench.common import progress, save_figure
from hair_sim.bench.scenarios import demo
from hair_sim.physics.params import STYLED_SHAPE_STIFFNESS
from hair_sim.physics.simulator import DEFAULT_DT, HairSimulator
from hair_sim.physics.simulator import SUBSTEPS_PER_60HZ_FRAME as SUBSTEPS
from hair_sim.render import HairRenderer
from hair_sim.sinks.markers import MarkerEncoder, MarkerLayout
from hair_sim.sinks.mesh_msg import hair_mesh_cdr, hair_mesh_topology_cdr

THESIS_FPS = {20: 81, 52: 79, 84: 67, 116: 59, 148: 46, 180: 41}
STRIPS_FULL = [20, 52, 84, 116, 148, 180, 500, 1000, 2000]
STRIPS_QUICK = [20, 180]
# (model, solver steps per 60 Hz frame, shape_stiffness): the default sim_rate for both,
# and the articulated model at one step per frame, exact and with the shape springs the
# README suggests for styled hair
CONFIGS = (('anjyo', SUBSTEPS, 0.0), ('articulated', SUBSTEPS, 0.0), ('articulated', 1, 0.0),
           ('articulated', 1, STYLED_SHAPE_STIFFNESS))
FRAME_RATE = 60.0
# whole passes over every case, interleaved; each case reports its median pass. This
# machine's speed moved by up to 1.7 times within minutes (2026-11-27: three passes in ten
# minutes gave the thesis model 467, 404 and 456 fps at 180 strips, 79, 64 and 60 at 1000)
ROUNDS = 3
MARKER_RATE = 10.0             # the node's shipped marker_rate: markers in 1 frame of 6
TEXTURE_EVERY = 30             # before the split, HairMesh carried the PNG every 30th message


def bytes_before_split(mesh_bytes, topology, topology_bytes):
    """
    Return the mean bytes of a HairMesh before the topology split, per message.

    That message carried the vertices, UVs, indices, offsets and strip ids every time and
    the PNG every TEXTURE_EVERY-th: the two messages of now, less the PNG but once in
    TEXTURE_EVERY, and less one header and topology id (within a few bytes).
    """
    png = len(topology.texture_png)
    return mesh_bytes + topology_bytes - png + png / TEXTURE_EVERY


def meshcat_encode(mesh):
    """Encode the hair as the meshcat sink does (SetObject lowered and packed)."""
    from meshcat.commands import SetObject
    import umsgpack
    from hair_sim.sinks.meshcat_sink import hair_object, node_path
    return umsgpack.packb(SetObject(hair_object(mesh), path=node_path('/hair_sim/hair')).lower())


def median_ms(fn, repeats):
    """Return the median wall time of fn() in ms (one core, after a warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def demo_scene(n_strips, model='anjyo', dt=DEFAULT_DT, shape_stiffness=0.0):
    """Return (simulator, step) of thesis_long with n_strips under the demo's head and wind."""
    style = load_hairstyle(paths.shipped_style('thesis_long')).with_strip_count(n_strips)
    sim = HairSimulator(style, model=model, shape_stiffness=shape_stiffness)
    sim.set_head_pose(0.0, *demo(0.0))
    sim.set_wind([2.0, 0.5, 0.0], turbulence=0.3, seed=2)
    clock = [0.0]

    def step():
        clock[0] += dt
        sim.set_head_pose(clock[0], *demo(clock[0]))
        sim.step(dt)

    for _ in range(20):
        step()
    return sim, step


def physics_frame_ms(step, steps, frames):
    """Return the mean wall ms of `frames` 60 Hz frames of `steps` solver steps each."""
    t0 = time.perf_counter()
    for _ in range(frames * steps):
        step()
    return 1e3 * (time.perf_counter() - t0) / frames


def row(n_strips, repeats, model='anjyo', steps=SUBSTEPS, shape_stiffness=0.0):
    """
    Measure one style size with one strand model at `steps` solver steps per 60 Hz frame.

    physics_step_ms is the median step (end to end counts `steps` of it); the articulated
    model's substeps come in bursts where the gusts whip a tip, so the mean over 2 s of
    frames is reported too (physics_frame_ms_mean, end_to_end_fps_mean).
    """
    sim, step = demo_scene(n_strips, model, 1.0 / (FRAME_RATE * steps), shape_stiffness)
    step_ms = median_ms(step, repeats * SUBSTEPS)
    frame_mean_ms = physics_frame_ms(step, steps, int(2 * FRAME_RATE))
    renderer = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    # renderer.mesh, not mesh_of: that reuses the mesh of an unchanged state
    mesh_ms = median_ms(lambda: renderer.mesh(sim.pos, R, p), repeats)
    mesh = renderer.mesh(sim.pos, R, p)

    def hair_mesh():
        return hair_mesh_cdr(mesh.vertices, mesh.strip_ids, 1, 'world', 0, 0)

    hair_mesh_ms = median_ms(hair_mesh, repeats)
    topology = renderer.topology()
    topology_bytes = len(hair_mesh_topology_cdr(topology, 1, 'world', 0, 0))
    layout = MarkerLayout(sim.strips.n_strips, mesh.tris_per_strip, mesh)

    encoder = MarkerEncoder(layout, mesh.texture_id, mesh.texture_png, 'head')

    def markers():
        return encoder.encode(mesh, R, p, 0, 0)

    marker_ms = median_ms(markers, repeats)
    meshcat_ms = median_ms(lambda: meshcat_encode(mesh), max(3, repeats // 3))
    drawing_ms = mesh_ms + hair_mesh_ms + marker_ms * MARKER_RATE / FRAME_RATE
    frame_ms = steps * step_ms + drawing_ms
    every_frame_ms = steps * step_ms + mesh_ms + hair_mesh_ms + marker_ms
    mesh_bytes = len(hair_mesh())
    return {'model': model, 'strips': n_strips,
            'simulated_vertices': int(sim.pos.shape[0] * sim.pos.shape[1]),
            'rendered_vertices': int(len(mesh.vertices)), 'physics_step_ms': step_ms,
            'substeps_per_frame': steps, 'sim_rate': FRAME_RATE * steps,
            'shape_stiffness': shape_stiffness,
            'physics_frame_ms_mean': frame_mean_ms, 'frame_ms': mesh_ms,
            'hair_mesh_ms': hair_mesh_ms,
            'hair_mesh_bytes': mesh_bytes, 'hair_mesh_topology_bytes': topology_bytes,
            'hair_mesh_bytes_before_split': bytes_before_split(mesh_bytes, topology,
                                                               topology_bytes),
            'marker_bytes_ms': marker_ms, 'marker_bytes': len(markers()),
            'meshcat_encode_ms': meshcat_ms, 'end_to_end_ms': frame_ms,
            'end_to_end_fps': 1e3 / frame_ms,
            'end_to_end_fps_mean': 1e3 / (frame_mean_ms + drawing_ms),
            'end_to_end_fps_markers_every_frame': 1e3 / every_frame_ms,
            'thesis_fps': THESIS_FPS.get(n_strips)}


def run(quick=False, plot_dir=None):
    """
    Measure every size with both models (CONFIGS), ROUNDS times over; the median of each.

    The meshcat encoding runs on its own thread in the node, so end to end counts what the
    node's own thread does for a 60 Hz frame: the physics substeps, the U-shape, the
    hair_mesh bytes, and the marker bytes at the shipped marker_rate (one frame in six;
    end_to_end_fps_markers_every_frame counts them in every frame).
    """
    sizes = STRIPS_QUICK if quick else STRIPS_FULL
    cases = [c + (n,) for c in CONFIGS for n in sizes]
    rounds = 1 if quick else ROUNDS
    runs = [[row(n, 5 if quick else 30, model, steps, shape)
             for model, steps, shape, n in cases]
            for _ in progress(range(rounds), 'scale rounds')]
    # per case, the round with the median end-to-end rate (a whole measured row, so that
    # its parts add up), and every round's rate beside it
    records = []
    for i in range(len(cases)):
        rows = sorted((run[i] for run in runs), key=lambda r: r['end_to_end_fps'])
        median = dict(rows[len(rows) // 2])
        median['end_to_end_fps_rounds'] = [r['end_to_end_fps'] for r in rows]
        records.append(median)
    if plot_dir:
        plot(records, plot_dir)
    return records


def plot(records, plot_dir):
    """Plot fps and per-stage ms against strips."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for (model, steps, shape), style in zip(CONFIGS, ('o-', 'v-', '^-', 'd-')):
        rs = [r for r in records if r['model'] == model and r['substeps_per_frame'] == steps
              and r['shape_stiffness'] == shape]
        a.loglog([r['strips'] for r in rs], [r['end_to_end_fps'] for r in rs], style,
                 label='hair_sim end to end, %s%s, %d step%s a frame'
                 % (model, ' + shape springs' if shape else '', steps,
                    '' if steps == 1 else 's'))
    t = [r for r in records if r['thesis_fps'] and r['model'] == 'anjyo']
    a.loglog([r['strips'] for r in t], [r['thesis_fps'] for r in t], 's--',
             label='thesis table 5.1 (2003)')
    a.axhline(60, color='0.6', ls=':', lw=0.8)
    a.set_xlabel('strips')
    a.set_ylabel('frames per second')
    a.legend(fontsize=7)
    rs = [r for r in records if r['model'] == 'anjyo' and r['substeps_per_frame'] == SUBSTEPS]
    n = [r['strips'] for r in rs]
    series = (('physics_step_ms', 'physics step'), ('frame_ms', 'tessellation + U-shape'),
              ('hair_mesh_ms', 'hair_mesh bytes'), ('marker_bytes_ms', 'marker bytes'),
              ('meshcat_encode_ms', 'meshcat encode'),
              ('end_to_end_ms', 'end to end (%d steps)' % rs[0]['substeps_per_frame']))
    for key, label in series:
        b.loglog(n, [r[key] for r in rs], 'o-', label=label)
    chains = [c for c in CONFIGS if c[0] == 'articulated']
    for (model, steps, shape), style in zip(chains, ('v--', '^--', 'd--')):
        ra = [r for r in records if r['model'] == model
              and r['substeps_per_frame'] == steps and r['shape_stiffness'] == shape]
        b.loglog([r['strips'] for r in ra], [r['physics_frame_ms_mean'] for r in ra], style,
                 label='physics of a frame (mean), articulated%s, %d step%s'
                 % (' + shape springs' if shape else '', steps, '' if steps == 1 else 's'))
    b.set_xlabel('strips')
    b.set_ylabel('ms (anjyo unless marked)')
    b.legend(fontsize=7)
    fig.suptitle('hair_sim_bench scale (one core)')
    path = save_figure(fig, '%s/scale.png' % plot_dir)
    plt.close(fig)
    return path
