"""
No numba kernel is called with more than 8 positional arguments that are not bundled.

Kernels bundle their state and parameters (namedtuples or tuples of arrays) and list one
argument per line at call sites, like PyElastica's. A fresh process with an empty numba
cache runs both models and the renderer (so every kernel, nested ones too, is compiled
and keeps the signatures it was called with); every signature is then read: a bundle is
a (named) tuple there, anything else counts.
"""

import json
import os
import subprocess
import sys

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
                rows.append([name, len(loose), str(signature)])
print(json.dumps(rows))
'''


def test_no_kernel_is_called_with_more_than_eight_unbundled_arguments(tmp_path):
    """Every compiled signature of every kernel in the package, counted."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'numba'))
    out = subprocess.run([sys.executable, '-c', SCAN], env=env, capture_output=True,
                         text=True, timeout=600, check=True).stdout
    rows = json.loads(out.strip().splitlines()[-1])
    compiled = {name for name, _, _ in rows}
    # the scan saw what it is meant to check (it would pass vacuously otherwise)
    for name in ('integrate_strands', 'thesis_substep', 'step_chains', 'external_forces',
                 'reaction_constraint_forces', 'strip_springs', 'filter_head_motion',
                 '_stop_inward_motion', '_recentre', '_moments_of_trig', 'visible_strips'):
        assert name in compiled, name
    too_long = ['%s: %d unbundled %s' % tuple(row) for row in rows if row[1] > MAX_UNBUNDLED]
    assert not too_long, too_long
