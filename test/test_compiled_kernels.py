"""
Every kernel compiled afresh: what each looks like, and what `make setup`'s warm-up caches.

One process compiles the whole package from an empty numba cache: it runs the warm-up,
keeps a copy of the cache the warm-up filled, then drives the rest of the scan below and
reads every kernel's machine code. (The scan and the warm-up each compiled the package in
a process of its own before: 114 s side by side for the five tests on an idle 2-core
machine, and 121 s of one worker's time in the suite's shared pass, both cores busy.)

What every compiled kernel looks like: its arguments bundled, no reference counting, and
the articulated model's lane loops vectorised.

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

BIN = os.path.dirname(sys.executable)

MAX_UNBUNDLED = 8

# argv[1]: where the copy of the warm-up's cache goes; WARMED is printed once it is made
WARMED = 'hair_sim test: the warm-up has returned'

SCAN = r'''
import importlib, json, os, pkgutil, shutil, sys
from hair_sim import warmup
code = warmup.main()
shutil.copytree(os.environ['NUMBA_CACHE_DIR'], sys.argv[1])
print(%r, code, flush=True)
''' % WARMED + r'''
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
                # double multiplies, packed (mulpd, vmulpd) and one at a time (mulsd, vmulsd)
                rows.append([name, len(loose), str(signature), refcounts,
                             asm.count('mulpd'), asm.count('mulsd')])
print(json.dumps(rows))
'''


# Kernels that allocate (their scratch or their result) once a call, so numba counts
# references in them; none of them runs per strand or per vertex. And twist_free_chains,
# which takes a view of each joint's frame: it runs once a placement (the articulated
# model started from given directions: a model switch, set_strand_directions), never in a
# frame. The scan saw it once it ran the warm-up, which switches the node's model.
ALLOCATING = {'shadow_cones', 'culled_triangles', 'filter_head_motion', 'rotation_vector',
              'twist_free_chains'}


@pytest.fixture(scope='module')
def fresh_compiles(tmp_path_factory):
    """
    Return the scan's and the warm-up's (returncode, output, cache directory).

    One process, an empty numba cache of its own and numba's cache log on: the warm-up's
    output is what it printed up to WARMED, and its cache the copy made then, before the
    scan compiled anything more.
    """
    where = tmp_path_factory.mktemp('fresh')
    env = dict(os.environ, NUMBA_CACHE_DIR=str(where / 'numba'), NUMBA_DEBUG_CACHE='1')
    # stderr into stdout's file, unbuffered, so in order (numba's cache log is on stdout)
    with open(where / 'out', 'w') as out:
        run = subprocess.run([sys.executable, '-u', '-c', SCAN, str(where / 'warm')], env=env,
                             stdout=out, stderr=subprocess.STDOUT, timeout=900)
    text = (where / 'out').read_text()
    cut = text.find(WARMED)
    if cut < 0:                                       # the warm-up itself failed
        return {'warmup': (run.returncode, text, where / 'warm'),
                'scan': (run.returncode, text)}
    end = text.index('\n', cut)
    warm_code = int(text[cut:end].split()[-1])
    return {'warmup': (warm_code, text[:cut], where / 'warm'),
            'scan': (run.returncode, text[end + 1:])}


@pytest.fixture(scope='module')
def compiled(fresh_compiles):
    """
    Return one row per compiled signature.

    (name, unbundled arguments, signature, reference-count calls, packed and scalar double
    multiplies)
    """
    code, out = fresh_compiles['scan']
    assert code == 0, out[-4000:]
    return json.loads([line for line in out.splitlines() if line.startswith('[[')][-1])


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


# The articulated step's loops over its lanes (articulated.LANES strands a vector register)
LANE_LOOPS = ('_drift_turn', '_drift_to_mid', '_body_inertia', '_contact_mass',
              '_joint_rotation', '_joint', '_accelerations', '_kick_turn', '_drift_to_end',
              '_place')


def test_the_chain_steps_lane_loops_are_vectorised(compiled):
    """
    Each loop over the articulated step's lanes multiplies doubles packed, not one at a time.

    LLVM vectorises a loop only when it can prove its accesses apart and every call in it
    has a vector form: a libm call, a field reached off another base, or a helper numba
    does not inline leaves the loop scalar, and the step twice as slow (0.18 -> 0.36 us a
    segment-substep on the hanging scene), with nothing else to show for it. The scalar
    passes between them (libm's atan2, the guard) are the checks that this can fail.
    """
    assert_scanned(compiled, LANE_LOOPS + ('_guard_lane',))
    for row in compiled:
        if row[0] in LANE_LOOPS:
            # (a loop left scalar may still pack a few pairs of its multiplies: SLP)
            assert row[4] > 0 and row[5] == 0, '%s %s: %d packed, %d scalar multiplies' % (
                row[0], row[2], row[4], row[5])
    # and the check can fail: the guard's pass is scalar
    assert any(row[5] > row[4] for row in compiled if row[0] == '_guard_lane')


def _cache_log(output):
    """Return the numba cache log's (saved, loaded) data lines."""
    lines = [line for line in output.splitlines() if line.startswith('[cache] data')]
    return ([line for line in lines if 'data saved' in line],
            [line for line in lines if 'data loaded' in line])


def test_after_the_warmup_the_demo_compiles_no_kernel(fresh_compiles):
    """
    The warm-up fills an empty cache; the demo's node then only loads from it.

    numba compiles at a kernel's first call; a fresh install's first `make demo` stalled
    for 10 s compiling. The warm-up (python -m hair_sim.warmup) drives the node's callbacks
    for both strand models so that numba's on-disk cache holds them. Checked with numba's
    cache log: the warm-up saves kernels, then the demo run as `make demo` runs it loads
    them and saves none (a kernel the warm-up missed would be compiled and saved there).
    The warm-up says nothing of its node's dropped time: every `make setup` printed "the
    node clock moved 131 ms beyond 16 steps ... raise max_steps_per_frame", of a node the
    user does not run.
    """
    code, out, cache = fresh_compiles['warmup']
    assert code == 0, out[-4000:]
    assert 'compiled and cached' in out
    assert '[WARN]' not in out, [line for line in out.splitlines() if '[WARN]' in line]
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), NUMBA_DEBUG_CACHE='1')
    saved, _ = _cache_log(out)
    assert len(saved) > 20, 'the warm-up compiled almost nothing: %d kernels' % len(saved)
    demo = subprocess.run([os.path.join(BIN, 'hair_sim_demo'), '--duration', '4',
                           '--no-meshcat'], env=env, capture_output=True, text=True,
                          timeout=120)
    assert demo.returncode == 0, demo.stdout[-2000:] + demo.stderr[-2000:]
    saved, loaded = _cache_log(demo.stdout + demo.stderr)
    assert loaded, 'the demo loaded no kernel from the cache'
    assert not saved, 'the demo compiled kernels the warm-up did not:\n' + '\n'.join(saved)


# A library user's scene: strands on their own (no inter-strip springs) under a still head
# and no wind, where the simulator checks a retried step's energy (the hanging scene).
HANGING = r'''
from hair_sim.bench.hanging import head_model, rest_strands, scene_params
from hair_sim.physics.simulator import HairSimulator
sim = HairSimulator.from_strands(rest_strands(20, 10), head_model(),
                                 **scene_params('articulated'))
sim.set_head_pose(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
for _ in range(30):
    sim.step(1.0 / 60.0)
print(sim.counters['strand_substeps'])
'''


def test_after_the_warmup_a_still_head_with_strands_apart_compiles_no_kernel(fresh_compiles):
    """
    The kernels a step calls only when nothing could give the strands energy are cached too.

    With the head still, no wind and strands not joined by springs, a strand whose swing
    outran its substeps has its energy checked (strand_energies) away from the spheres
    (keep_strands_clear_of_spheres). The demo's styles join their strands, so driving the
    node never calls them: a from_strands scene's first step compiled them for 0.85 s.
    """
    code, out, cache = fresh_compiles['warmup']
    assert code == 0, out[-4000:]
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), NUMBA_DEBUG_CACHE='1')
    run = subprocess.run([sys.executable, '-c', HANGING], env=env, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    saved, loaded = _cache_log(run.stdout + run.stderr)
    assert loaded, 'the scene loaded no kernel from the cache'
    assert not saved, 'the scene compiled kernels the warm-up did not:\n' + '\n'.join(saved)
