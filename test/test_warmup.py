"""
`make setup`'s warm-up: after it, the demo's node compiles no kernel.

numba compiles at a kernel's first call; a fresh install's first `make demo` stalled for
10 s compiling. The warm-up (python -m hair_sim.warmup) drives the node's callbacks for both strand
models so that numba's on-disk cache holds them. Checked in a cache directory of its own,
with numba's cache log: the warm-up saves kernels, then the demo run as `make demo` runs it
loads them and saves none (a kernel the warm-up missed would be compiled and saved there).
"""

import os
import subprocess
import sys

BIN = os.path.dirname(sys.executable)


def _cache_log(output):
    """Return the numba cache log's (saved, loaded) data lines."""
    lines = [line for line in output.splitlines() if line.startswith('[cache] data')]
    return ([line for line in lines if 'data saved' in line],
            [line for line in lines if 'data loaded' in line])


def test_after_the_warmup_the_demo_compiles_no_kernel(tmp_path):
    """The warm-up fills an empty cache; the demo's node then only loads from it."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'numba'), NUMBA_DEBUG_CACHE='1')
    warm = subprocess.run([sys.executable, '-m', 'hair_sim.warmup'], env=env,
                          capture_output=True, text=True, timeout=600)
    assert warm.returncode == 0, warm.stdout[-2000:] + warm.stderr[-2000:]
    assert 'compiled and cached' in warm.stdout
    saved, _ = _cache_log(warm.stdout + warm.stderr)
    assert len(saved) > 20, 'the warm-up compiled almost nothing: %d kernels' % len(saved)
    demo = subprocess.run([os.path.join(BIN, 'hair_sim_demo'), '--duration', '4',
                           '--no-meshcat'], env=env, capture_output=True, text=True,
                          timeout=120)
    assert demo.returncode == 0, demo.stdout[-2000:] + demo.stderr[-2000:]
    saved, loaded = _cache_log(demo.stdout + demo.stderr)
    assert loaded, 'the demo loaded no kernel from the cache'
    assert not saved, 'the demo compiled kernels the warm-up did not:\n' + '\n'.join(saved)
