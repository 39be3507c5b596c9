"""
Where hair_sim's shipped configuration lives.

In order: the work tree (a clone, or an editable install), the share/ files pip installed
with this very copy of the package (setup.py's data_files: `pip install .` into a venv, or
`--prefix`, `--target`), the ament index (a colcon install, AMENT_PREFIX_PATH).
"""

import functools
from importlib import metadata
import os

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))   # (numba caches kernels beside it)
_SHARE_CONFIG = ('share', 'hair_sim', 'config')


@functools.lru_cache(maxsize=None)
def _installed_config():
    """
    Return the config/ that pip installed with this copy of hair_sim, or None.

    Looked up once a process: reading the distributions' file records took 1.1 ms, and
    config_dir() is called several times a style load or save.

    The distribution is the one whose recorded files hold this module (another copy on
    the path, an editable one, has other data or none). Its data files are recorded
    relative to its site-packages (../../../share/hair_sim/config/...), wherever the
    scheme put them; `pip install --target DIR` puts them in DIR/share but records them
    as if DIR were a site-packages, so DIR/share is looked in as well. Before, only the
    work tree and the ament index were: after `pip install .` into a venv (no
    AMENT_PREFIX_PATH, as the PyPI ROS wheels run), `hair_sim_node` exited with "no
    hairstyle 'thesis_long' in .../site-packages/config/hairstyles".
    """
    here = os.path.realpath(__file__)
    candidates = []
    for dist in metadata.distributions(name='hair_sim'):
        files = dist.files or ()
        if not any(os.path.realpath(dist.locate_file(f)) == here
                   for f in files if f.name == 'paths.py'):
            continue
        candidates += [os.path.dirname(os.path.realpath(dist.locate_file(f))) for f in files
                       if f.name == 'hair_sim.yaml' and tuple(f.parts[-4:-1]) == _SHARE_CONFIG]
        candidates.append(os.path.join(os.path.dirname(PACKAGE_DIR), *_SHARE_CONFIG))
    for found in candidates:
        if os.path.isdir(os.path.join(found, 'hairstyles')):
            return found
    return None


def config_dir():
    """Return the directory holding hair_sim.yaml, heads/ and hairstyles/."""
    tree = os.path.join(os.path.dirname(PACKAGE_DIR), 'config')
    if os.path.isdir(os.path.join(tree, 'hairstyles')):
        return tree
    installed = _installed_config()
    if installed is not None:
        return installed
    try:
        from ament_index_python.packages import get_package_share_directory
        return os.path.join(get_package_share_directory('hair_sim'), 'config')
    except (ImportError, LookupError, OSError):
        return tree


def heads_dir():
    """Return the shipped head models directory."""
    return os.path.join(config_dir(), 'heads')


def hairstyles_dir():
    """Return the shipped hairstyles directory."""
    return os.path.join(config_dir(), 'hairstyles')


def shipped_style(name):
    """Return the path of a shipped hairstyle by name (without .yaml)."""
    return os.path.join(hairstyles_dir(), name + '.yaml')


# The hairstyles the package ships (tools/make_styles.py makes them). A style a user saves
# into hairstyles_dir() (the only hairstyle directory by default) is not one of them: the
# node's save never replaces these, and the tests and benchmarks run these.
SHIPPED_STYLES = ('bob_fringe', 'side_swept_long', 'thesis_long', 'thesis_short')


def shipped_style_names():
    """Return the names of the shipped hairstyles, sorted (without .yaml)."""
    return sorted(SHIPPED_STYLES)


def shipped_head(name):
    """Return the path of a shipped head model by name (without .yaml)."""
    return os.path.join(heads_dir(), name + '.yaml')
