"""A non-editable install finds the configuration it installed, without ROS's environment."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from hair_sim import paths

ROOT = os.path.dirname(paths.config_dir())
SOURCES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'config', 'hair_sim')

# run by the installed copy, from a folder that is not the work tree
PROBE = """
import json
import hair_sim
from hair_sim import load_hairstyle, load_head, paths
styles = {name: load_hairstyle(paths.shipped_style(name)).n_strips
          for name in paths.shipped_style_names()}
head = load_head(paths.shipped_head('default_adult'))
print(json.dumps({'module': hair_sim.__file__, 'config': paths.config_dir(), 'styles': styles,
                  'head_triangles': len(head.display_mesh()[1])}))
"""


@pytest.mark.parametrize('where', ['--prefix', '--target'])
def test_a_pip_installed_copy_finds_its_shipped_styles_and_heads(tmp_path, where):
    """
    `pip install .` (not editable) puts config/ in <prefix>/share/hair_sim: it is found.

    The PyPI ROS wheels set no AMENT_PREFIX_PATH, so the ament index finds nothing; before,
    the installed `hair_sim_node` then looked in site-packages/config and exited with "no
    hairstyle 'thesis_long' in .../site-packages/config/hairstyles", and so did every
    shipped style and head by name. --prefix lays files out as a venv install does;
    --target puts the data beside the package.
    """
    src = tmp_path / 'src'
    src.mkdir()
    for name in SOURCES:
        path = os.path.join(ROOT, name)
        if os.path.isdir(path):
            shutil.copytree(path, src / name,
                            ignore=shutil.ignore_patterns('__pycache__', '*.nbi', '*.nbc'))
        else:
            shutil.copy2(path, src / name)
    dest = tmp_path / 'installed'
    # --ignore-installed: with --prefix alone pip uninstalls the hair_sim of the environment
    # it runs in (the suite's own editable install) before installing the copy
    subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '--no-deps',
                    '--no-build-isolation', '--disable-pip-version-check', '--ignore-installed',
                    where, str(dest),
                    str(src)], check=True, capture_output=True, timeout=300)
    if where == '--prefix':
        site = dest / 'lib' / ('python%d.%d' % sys.version_info[:2]) / 'site-packages'
        share = dest / 'share' / 'hair_sim' / 'config'
    else:
        site = dest
        share = dest / 'share' / 'hair_sim' / 'config'
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH', 'PYTHONPATH')}
    env['PYTHONPATH'] = str(site)
    run = subprocess.run([sys.executable, '-c', PROBE], cwd=str(tmp_path), env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    found = json.loads(run.stdout.strip().splitlines()[-1])
    assert found['module'] == str(site / 'hair_sim' / '__init__.py')
    assert found['config'] == str(share)
    assert set(found['styles']) == set(paths.shipped_style_names())
    assert min(found['styles'].values()) > 0 and found['head_triangles'] > 0


# imports hair_sim, compiles one cached kernel, and says where numba cached it
CACHE_PROBE = """
import json, os
import hair_sim
from hair_sim import kernels
from hair_sim.vecmath import atan2_vectorizable
assert abs(atan2_vectorizable(1.0, 1.0) - 0.7853981633974483) < 1e-15
where = kernels.CACHE_DIR
saved = [f for _, _, fs in os.walk(where) for f in fs if f.endswith('.nbi')] if where else []
print(json.dumps({'cache_dir': where, 'saved': saved,
                  'mode': oct(os.stat(where).st_mode & 0o777) if where else None}))
"""


def _package_numba_cannot_cache_beside(tmp_path):
    """Copy hair_sim where numba cannot cache beside it: every __pycache__ is a file."""
    dest = tmp_path / 'site' / 'hair_sim'
    shutil.copytree(os.path.join(ROOT, 'hair_sim'), dest,
                    ignore=shutil.ignore_patterns('__pycache__', '*.nbi', '*.nbc'))
    for folder, _, _ in os.walk(dest):
        open(os.path.join(folder, '__pycache__'), 'w').close()
    return tmp_path / 'site'


def _run_cache_probe(site, tmp_dir, **extra):
    env = {k: v for k, v in os.environ.items() if not k.startswith('NUMBA_')}
    env.update(PYTHONPATH=str(site), PYTHONDONTWRITEBYTECODE='1', TMPDIR=str(tmp_dir),
               HOME='/proc', XDG_CACHE_HOME='/proc/no-cache-here', **extra)
    run = subprocess.run([sys.executable, '-c', CACHE_PROBE], cwd=str(tmp_dir), env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_a_copy_numba_cannot_cache_beside_for_a_user_without_a_cache_still_imports(tmp_path):
    """
    Installed where its user cannot write, run by a user with no writable home (a service).

    numba caches beside the source or in ~/.cache/numba, and a kernel it can cache in
    neither cannot be defined: `import hair_sim` raised "RuntimeError: cannot cache
    function 'atan2_vectorizable': no locator available" (a root-owned venv run as nobody,
    2026-12-01). Now the kernels are cached in <tmp>/hair_sim-numba-<uid>, made private.
    (Root can write anywhere, so here each __pycache__ is a file and the cache home /proc.)
    """
    site = _package_numba_cannot_cache_beside(tmp_path)
    tmp_dir = tmp_path / 'tmp'
    tmp_dir.mkdir()
    found = _run_cache_probe(site, tmp_dir)
    assert found['cache_dir'] == str(tmp_dir / ('hair_sim-numba-%d' % os.getuid()))
    assert found['mode'] == '0o700' and found['saved'], found
    again = _run_cache_probe(site, tmp_dir)                 # kept for the next run
    assert again['cache_dir'] == found['cache_dir']
    chosen = _run_cache_probe(site, tmp_dir, NUMBA_CACHE_DIR=str(tmp_path / 'chosen'))
    assert chosen['cache_dir'] is None                      # the user's own choice stands


def test_a_cache_folder_someone_else_could_write_is_not_used(tmp_path):
    """<tmp>/hair_sim-numba-<uid> open to others (planted machine code) is passed over."""
    site = _package_numba_cannot_cache_beside(tmp_path)
    tmp_dir = tmp_path / 'tmp'
    planted = tmp_dir / ('hair_sim-numba-%d' % os.getuid())
    planted.mkdir(parents=True)
    planted.chmod(0o777)
    found = _run_cache_probe(site, tmp_dir)
    assert found['cache_dir'] != str(planted)
    assert os.path.dirname(found['cache_dir']) == str(tmp_dir), found
    assert found['mode'] == '0o700' and found['saved'], found
    assert not os.listdir(planted)
