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
