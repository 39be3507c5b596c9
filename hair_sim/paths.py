"""Where hair_sim's shipped configuration lives (work tree, or the ament share directory)."""

import os

_PKG_DIR = os.path.dirname(os.path.abspath(__file__))


def config_dir():
    """Return the directory holding hair_sim.yaml, heads/ and hairstyles/."""
    tree = os.path.join(os.path.dirname(_PKG_DIR), 'config')
    if os.path.isdir(os.path.join(tree, 'hairstyles')):
        return tree
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
