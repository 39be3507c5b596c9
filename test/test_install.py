"""How hair_sim is installed: pip layouts, read-only installs, make setup's venvs."""

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


def _copy_source(name, dest):
    """Copy a file or folder of the work tree, without bytecode or numba's caches."""
    path = os.path.join(ROOT, name)
    if os.path.isdir(path):
        shutil.copytree(path, dest, ignore=shutil.ignore_patterns('__pycache__', '*.nbi', '*.nbc'))
    else:
        shutil.copy2(path, dest)


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
        _copy_source(name, src / name)
    dest = tmp_path / 'installed'
    # --ignore-installed: with --prefix alone pip uninstalls the hair_sim of the environment
    # it runs in (the suite's own editable install) before installing the copy
    subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '--no-deps',
                    '--no-build-isolation', '--disable-pip-version-check', '--ignore-installed',
                    where, str(dest),
                    str(src)], check=True, capture_output=True, timeout=300)
    site = dest / 'lib' / ('python%d.%d' % sys.version_info[:2]) / 'site-packages' \
        if where == '--prefix' else dest
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
    _copy_source('hair_sim', dest)
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


def test_each_venv_builds_the_messages_in_a_folder_of_its_own(tmp_path):
    """
    `make setup VENV=other` builds hair_sim_msgs against that venv's ROS, not another's.

    CMake's cache remembers where it found ament_cmake: with one build/msg_defs for every
    venv, a second venv's messages were configured against the first venv's ament
    (measured: "Found ament_cmake: 2.5.4 (/work/main/.venv/share/ament_cmake/cmake)",
    its libraries' RUNPATH /work/main/.venv/lib), and a Python 3.12 venv failed there.
    """
    if shutil.which('make') is None:
        pytest.skip('no make')
    venv = tmp_path / 'other_venv'
    dry = subprocess.run(['make', '-n', '-C', ROOT, 'setup', 'VENV=%s' % venv],
                         capture_output=True, text=True, timeout=60)
    calls = [line.split() for line in dry.stdout.splitlines() if 'build_msgs.sh' in line]
    assert calls, dry.stdout[-2000:] + dry.stderr[-2000:]
    for call in calls:
        script = next(i for i, word in enumerate(call) if word.endswith('build_msgs.sh'))
        prefix, build = call[script + 1:script + 3]
        assert prefix == str(venv)
        build = os.path.join(ROOT, build)                 # (a relative one is make's cwd's)
        assert os.path.commonpath([build, str(venv)]) == str(venv), call


@pytest.mark.parametrize('python', ['3.12', 'empty', 'missing'])
def test_make_setup_refuses_a_python_that_is_not_3_11_in_one_line(tmp_path, python):
    """
    The pinned ROS wheels and build tools need 3.11: another Python is refused up front.

    python3.12 got as far as building the messages (the pinned setuptools then fails on
    its own pkgutil.ImpImporter), and an empty BOOT_PYTHON (neither python3.11 nor python3
    on PATH) made the recipe's "$(BOOT_PYTHON) -m venv" a line make ran as "m venv",
    its error ignored, the leading "-" taken as make's own prefix.
    """
    if shutil.which('make') is None:
        pytest.skip('no make')
    fake = tmp_path / 'python3.12'
    fake.write_text('#!/bin/sh\n[ "$1" = --version ] && echo "Python 3.12.1" && exit 0\n'
                    'exit 1\n')
    fake.chmod(0o755)
    boot = {'3.12': str(fake), 'empty': '', 'missing': str(tmp_path / 'nothing')}[python]
    venv = tmp_path / 'venv'
    run = subprocess.run(['make', '-C', ROOT, 'setup', 'VENV=%s' % venv,
                          'BOOT_PYTHON=%s' % boot], capture_output=True, text=True, timeout=60)
    assert run.returncode != 0
    assert 'hair_sim needs Python 3.11' in run.stderr, run.stderr
    assert ('Python 3.12.1' if python == '3.12' else 'not a Python') in run.stderr
    assert not venv.exists()
