"""The shipped hairstyles load, have the promised counts and sit on the default head."""

import os

import numpy as np
import pytest

from hair_sim import paths
from hair_sim.modeling import build_strips, load_hairstyle
from helpers.styles import footprint_coverage

STYLES = [paths.shipped_style(n) for n in paths.shipped_style_names()]


def test_at_least_four_styles_ship():
    """thesis_long, thesis_short and two more are shipped."""
    names = {os.path.basename(s)[:-5] for s in STYLES}
    assert {'thesis_long', 'thesis_short'} <= names and len(names) >= 4


def test_shipped_styles_are_the_tracked_files_and_saves_keep_off_them(tmp_path, monkeypatch):
    """
    SHIPPED_STYLES names the hairstyle files git tracks; a save never replaces one of them.

    A style a user saved beside them (the shipped directory is the only hairstyle directory
    by default) is refused without overwrite and replaced with it; a new name is written.
    """
    import subprocess

    from hair_sim.modeling.errors import HairstyleError
    from hair_sim.modeling.safepath import resolve_save_path
    root = os.path.dirname(paths.config_dir())
    out = subprocess.run(['git', 'ls-files', 'config/hairstyles'], cwd=root,
                         capture_output=True, text=True)
    if out.returncode != 0 or not out.stdout.strip():
        pytest.skip('not a git checkout')
    tracked = sorted(os.path.basename(f)[:-5] for f in out.stdout.split()
                     if f.endswith('.yaml'))
    assert tracked == paths.shipped_style_names()
    shipped_dir = tmp_path / 'hairstyles'
    shipped_dir.mkdir()
    for name in paths.SHIPPED_STYLES + ('mine',):
        (shipped_dir / (name + '.yaml')).write_text('x')
    monkeypatch.setattr(paths, 'hairstyles_dir', lambda: str(shipped_dir))
    for name in paths.SHIPPED_STYLES:
        for overwrite in (False, True):
            with pytest.raises(HairstyleError, match='shipped'):
                resolve_save_path(name, [''], overwrite)
    with pytest.raises(HairstyleError, match='exists'):
        resolve_save_path('mine', [''], False)
    assert resolve_save_path('mine', [''], True) == str(shipped_dir / 'mine.yaml')
    assert resolve_save_path('new', [''], False) == str(shipped_dir / 'new.yaml')


@pytest.mark.parametrize('path', STYLES, ids=lambda p: os.path.basename(p))
def test_style_sits_on_the_head(path):
    """Roots within 1 mm of the scalp, no vertex inside a head sphere, roots cover the scalp."""
    style = load_hairstyle(path)
    strips = build_strips(style)
    head = style.head
    roots = strips.rest[:, 0]
    assert np.abs(head.scalp_distance(roots)).max() < 1e-3
    assert head.collision_distance(roots).min() > -1e-3
    assert head.collision_distance(strips.rest[:, 1:]).min() > 0.0
    assert np.all(np.isfinite(strips.rest))
    assert head.in_hair_region(roots).all()
    # The hair grown from those roots covers the hair region: almost every scalp point of
    # the region has some strip point above it within 2 cm (seen from the head centre).
    assert footprint_coverage(style, strips) > 0.95


def test_thesis_long_counts():
    """The thesis' sample style: about 46 strips of 10 vertices."""
    style = load_hairstyle(paths.shipped_style('thesis_long'))
    strips = build_strips(style)
    assert strips.n_strips == 46 and strips.n_vertices == 10
    assert strips.rest.shape == (92, 10, 3)


def test_short_style_is_derived_from_the_long_one_by_control_points_only():
    """thesis_short has the long style's patches and roots, only moved control points."""
    long = load_hairstyle(paths.shipped_style('thesis_long'))
    short = load_hairstyle(paths.shipped_style('thesis_short'))
    assert [p.name for p in long.patches] == [p.name for p in short.patches]
    for a, b in zip(long.patches, short.patches):
        assert a.points.shape == b.points.shape and a.strips == b.strips
        assert (a.degree_u, a.degree_v) == (b.degree_u, b.degree_v)
        np.testing.assert_array_equal(a.points[:, 0], b.points[:, 0])
    assert (long.vertices, long.render_rows) == (short.vertices, short.render_rows)

    def length(style):
        r = build_strips(style).rest
        return np.linalg.norm(np.diff(r, axis=1), axis=2).sum(axis=1).mean()

    assert length(short) < 0.6 * length(long)
