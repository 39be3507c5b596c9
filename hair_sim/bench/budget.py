"""
hair_sim_bench budget: the per-vertex costs behind hair_sim.budget, measured on one core.

For styles of several sizes: a solver step per simulated vertex (both models, the demo's
head motion and wind), and everything a published frame costs per drawn vertex (the
U-shape mesh, HairMesh and HairState bytes, MarkerArray bytes at marker_rate / publish_rate
of the frames, the meshcat encoding at meshcat.rate / publish_rate). Reports the medians,
the constants in hair_sim/budget.py, and the vertices one core runs at the default rates.
"""

import numpy as np

from hair_sim import budget
from hair_sim.bench.common import progress
from hair_sim.bench.scale import demo_scene, meshcat_encode, median_ms
from hair_sim.render.mesh import HairRenderer
from hair_sim.sinks.markers import MarkerEncoder, MarkerLayout
from hair_sim.sinks.mesh_msg import hair_mesh_cdr, hair_state_cdr

MARKER_SHARE = 10.0 / 30.0     # marker_rate / publish_rate (shipped)
MESHCAT_SHARE = 20.0 / 30.0    # meshcat.rate / publish_rate (shipped)


def measure(n_strips, model, repeats):
    """Return (simulated, drawn vertices, s per solver step, s per published frame)."""
    sim, step = demo_scene(n_strips, model)
    step_ms = median_ms(step, repeats * 4)
    renderer = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    mesh = renderer.mesh(sim.pos, R, p)
    encoder = MarkerEncoder(MarkerLayout(sim.strips.n_strips, mesh.tris_per_strip, mesh),
                            mesh.texture_id, mesh.texture_png, 'world')

    def frame():
        m = renderer.mesh(sim.pos, R, p)
        hair_mesh_cdr(m.vertices, m.strip_ids, 1, 'world', 0, 0)
        hair_state_cdr(sim.pos, False, 0.0, 'world', 0, 0)
    frame_ms = median_ms(frame, repeats)
    marker_ms = median_ms(lambda: encoder.encode(mesh, np.eye(3), np.zeros(3), 0, 0), repeats)
    meshcat_ms = median_ms(lambda: meshcat_encode(mesh), max(3, repeats // 3))
    per_frame = frame_ms + MARKER_SHARE * marker_ms + MESHCAT_SHARE * meshcat_ms
    return sim.pos.shape[0] * sim.pos.shape[1], len(mesh.vertices), 1e-3 * step_ms, \
        1e-3 * per_frame


def _fit(x, y):
    """Return (fixed, per unit) of the least-squares line y = fixed + per * x."""
    per, fixed = np.polyfit(np.asarray(x, float), np.asarray(y, float), 1)
    return max(float(fixed), 0.0), float(per)


def run(quick=False, models=None):
    """Measure every model at a few sizes; fit fixed + per-vertex costs; compare."""
    from hair_sim.physics.params import MODELS
    sizes = [46, 180] if quick else [46, 180, 500, 1000]
    records = []
    for model in progress(models or MODELS, 'budget'):
        for n in sizes:
            sim_v, drawn_v, step_s, frame_s = measure(n, model, 5 if quick else 20)
            records.append({'model': model, 'strips': n, 'simulated_vertices': sim_v,
                            'drawn_vertices': drawn_v, 'step_s': step_s, 'frame_s': frame_s})
    summary = {}
    for model in models or MODELS:
        rs = [r for r in records if r['model'] == model]
        step_fixed, step_per = _fit([r['simulated_vertices'] for r in rs],
                                    [r['step_s'] for r in rs])
        frame_fixed, frame_per = _fit([r['drawn_vertices'] for r in rs],
                                      [r['frame_s'] for r in rs])
        summary[model] = {
            'step_fixed_s': step_fixed, 'step_s_per_vertex': step_per,
            'frame_fixed_s': frame_fixed, 'frame_s_per_drawn_vertex': frame_per,
            'in_budget_py': {'STEP_FIXED_S': budget.STEP_FIXED_S.get(model),
                             'STEP_S': budget.STEP_S.get(model),
                             'FRAME_FIXED_S': budget.FRAME_FIXED_S, 'DRAW_S': budget.DRAW_S},
            'max_vertices_at_default_rates': budget.max_vertices(model=model)}
    return {'records': records, 'summary': summary, 'cpu_share': budget.CPU_SHARE}
