"""
What every compiled kernel looks like: its arguments bundled, and no reference counting.

Kernels bundle their state and parameters (namedtuples or tuples of arrays) and list one
argument per line at call sites, like PyElastica's: no numba kernel is called with more
than 8 positional arguments that are not bundled. And no kernel pays numba's atomic
reference counts (NRT_incref / NRT_decref, see hair_sim.kernels) except the few that
allocate their scratch once a call. A fresh process with an empty numba cache runs both
models and the renderer (so every kernel, nested ones too, is compiled and keeps the
signatures it was called with); every signature and its machine code is then read: a
bundle is a (named) tuple there, anything else counts.
"""

import json
import os
import subprocess
import sys

import pytest

MAX_UNBUNDLED = 8

SCAN = r'''
import importlib, json, pkgutil
from numba.core import types
from numba.core.registry import CPUDispatcher
import hair_sim
from hair_sim import HairSimulator, load_hairstyle, paths
from hair_sim.bench.scenarios import drive, violent
from hair_sim.render import HairRenderer
style = load_hairstyle(paths.shipped_style('bob_fringe')).with_strip_count(8)
for model in ('anjyo', 'articulated'):
    sim = HairSimulator(style, model=model)
    sim.set_wind([2.0, 0.0, 0.0], turbulence=0.3, seed=1)
    drive(sim, violent, 0.0, 0.2, 1.0 / 240)
    renderer = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    renderer.mesh(sim.pos, R, p)
    renderer.mesh(sim.pos, R, p, viewpoint=p + R @ [0.6, 0.0, 0.0])     # culled
rows = []
for info in pkgutil.walk_packages(hair_sim.__path__, 'hair_sim.'):
    try:
        module = importlib.import_module(info.name)
    except ImportError:
        continue
    for name, obj in vars(module).items():
        if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
            for signature in obj.signatures:
                loose = [t for t in signature if not isinstance(t, types.BaseTuple)]
                asm = obj.inspect_asm(signature)
                refcounts = asm.count('NRT_incref') + asm.count('NRT_decref')
                rows.append([name, len(loose), str(signature), refcounts])
print(json.dumps(rows))
'''


# Kernels that allocate (their scratch or their result) once a call, so numba counts
# references in them; none of them runs per strand or per vertex.
ALLOCATING = {'shadow_cones', 'culled_triangles', 'filter_head_motion', 'rotation_vector'}


@pytest.fixture(scope='module')
def compiled(tmp_path_factory):
    """Return (name, unbundled arguments, signature, reference-count calls) per signature."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path_factory.mktemp('numba')))
    out = subprocess.run([sys.executable, '-c', SCAN], env=env, capture_output=True,
                         text=True, timeout=600, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def assert_scanned(compiled, names):
    """Assert the scan saw these kernels (a check of its rows would pass vacuously else)."""
    seen = {row[0] for row in compiled}
    for name in names:
        assert name in seen, name


def test_no_kernel_is_called_with_more_than_eight_unbundled_arguments(compiled):
    """Every compiled signature of every kernel in the package, counted."""
    assert_scanned(compiled, ('integrate_strands', 'thesis_substep', 'step_chains',
                              'external_forces', 'reaction_constraint_forces', 'strip_springs',
                              'filter_head_motion', '_stop_inward_motion', '_recentre',
                              '_moments_of_trig', 'visible_strips'))
    too_long = ['%s: %d unbundled %s' % tuple(row[:3]) for row in compiled
                if row[1] > MAX_UNBUNDLED]
    assert not too_long, too_long


def test_no_kernel_but_the_allocating_ones_counts_references(compiled):
    """The per-frame kernels' machine code has no NRT_incref / NRT_decref call in it."""
    # the per-frame kernels of both models, the mesh and the culling
    assert_scanned(compiled, ('integrate_strands', 'thesis_substep', 'guard_segment',
                              'step_chains', '_speculative_contacts', 'external_forces',
                              'reaction_constraint_forces', 'strip_springs',
                              'project_to_scalp', 'tessellate_strips', '_strip_hidden',
                              'visible_strips', 'mesh_vertices'))
    counting = sorted('%s: %d reference-count calls in %s' % (row[0], row[3], row[2])
                      for row in compiled if row[3] and row[0] not in ALLOCATING)
    assert not counting, counting
    # and the check can fail: the allocating kernels do count
    assert any(row[3] for row in compiled if row[0] in ALLOCATING)
