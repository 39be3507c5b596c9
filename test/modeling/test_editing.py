"""Editing (thesis 6.1): move a control point, re-tessellate, save atomically, reload."""

import os
import subprocess
import sys

import numpy as np
from PIL import Image
import pytest

from hair_sim import paths
from hair_sim.modeling import build_strips, HairstyleError, load_hairstyle, save_hairstyle
from hair_sim.modeling import yamlio


@pytest.fixture
def style():
    """Load the shipped long style."""
    return load_hairstyle(paths.shipped_style('thesis_long'))


def test_edit_moves_only_nearby_strands(style):
    """Moving one control point changes the strands of that hair's B-spline support only."""
    before = build_strips(style)
    p = style.patches[0]
    new_pos = p.points[5, 4] + np.array([0.0, 0.03, 0.0])
    edited = style.with_control_point(0, 5, 4, new_pos)
    after = build_strips(edited)
    assert style.patches[0].points[5, 4] is not edited.patches[0].points[5, 4]
    np.testing.assert_array_equal(style.patches[0].points[5, 4], p.points[5, 4])
    moved = np.abs(after.rest - before.rest).max(axis=(1, 2)) > 1e-12
    t = p.knots_u
    lo, hi = t[5], t[5 + p.degree_u + 1]           # support of control hair 5
    in_patch0 = np.arange(after.n_strands) < 2 * p.strips
    u = after.strand_u
    assert moved.any()
    assert not moved[~in_patch0].any()
    assert np.all((u[moved] > lo) & (u[moved] < hi))
    # rows near the root are untouched: the edited point is the 5th of 7 along
    assert np.abs(after.rest[:, :2] - before.rest[:, :2]).max() < 1e-12


def test_edit_rejects_bad_indices_and_values(style):
    """Edits name what is wrong and leave the style as it was."""
    for args, frag in [((9, 0, 0, [0, 0, 0.2]), 'no patch 9'),
                       ((0, 40, 0, [0, 0, 0.2]), 'no control hair 40'),
                       ((0, 0, 9, [0, 0, 0.2]), 'no control point 9'),
                       ((0, 0, 3, [0, np.nan, 0.2]), '3 finite numbers'),
                       ((0, 0, 0, [0, 0, 0.5]), 'root')]:
        with pytest.raises(HairstyleError, match=frag):
            style.with_control_point(*args)


def test_edit_save_load_round_trip_is_exact(style, tmp_path):
    """Edit -> save -> load gives bit-identical control points and strips."""
    edited = style.with_control_point(0, 2, 3, [0.0123456789012345, 0.0987654321, 0.05])
    path = str(tmp_path / 'edited.yaml')
    save_hairstyle(edited, path)
    back = load_hairstyle(path)
    assert back.to_dict() == edited.to_dict()
    for a, b in zip(edited.patches, back.patches):
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.knots_u, b.knots_u)
    np.testing.assert_array_equal(build_strips(back).rest, build_strips(edited).rest)
    derived = style.derive('derived', vertices=12)
    save_hairstyle(derived, path)
    assert load_hairstyle(path).vertices == 12


def test_failed_save_leaves_old_file_intact(style, tmp_path, monkeypatch):
    """A crash while writing (fsync fails, like a full disk) keeps the previous file whole."""
    path = str(tmp_path / 'keep.yaml')
    save_hairstyle(style, path)
    before = open(path, 'rb').read()

    def boom(fd):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(yamlio.os, 'fsync', boom)
    edited = style.with_control_point(0, 0, 3, [0.0, 0.0, 0.15])
    with pytest.raises(OSError) as err:
        save_hairstyle(edited, path)
    assert err.value.errno == 28
    assert str(err.value).endswith(
        'could not write %s: No space left on device; the file there is unchanged' % path)
    assert open(path, 'rb').read() == before
    assert os.listdir(tmp_path) == ['keep.yaml']


def test_save_into_missing_directory_fails_cleanly(style, tmp_path):
    """Saving where no directory exists raises and writes nothing."""
    with pytest.raises(OSError, match='could not write .*x.yaml: .*; nothing written'):
        save_hairstyle(style, str(tmp_path / 'nope' / 'x.yaml'))
    assert os.listdir(tmp_path) == []


def test_preview_command_writes_obj_and_png(tmp_path):
    """Check that `python -m hair_sim.modeling` writes a parsable OBJ and a non-empty PNG."""
    obj, png = str(tmp_path / 's.obj'), str(tmp_path / 's.png')
    out = subprocess.run([sys.executable, '-m', 'hair_sim.modeling',
                          paths.shipped_style('bob_fringe'), '--export', obj, '--png', png],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    style = load_hairstyle(paths.shipped_style('bob_fringe'))
    strips = build_strips(style)
    lines = open(obj).read().splitlines()
    assert sum(ln.startswith('v ') for ln in lines) == strips.n_strands * strips.n_vertices
    faces = [ln for ln in lines if ln.startswith('f ')]
    assert len(faces) == strips.n_strips * (strips.n_vertices - 1)
    n_v = strips.n_strands * strips.n_vertices
    assert all(1 <= int(i) <= n_v for f in faces for i in f.split()[1:])
    img = np.asarray(Image.open(png).convert('RGB')).astype(float)
    hair = np.array(style.material['color']) * 255
    assert img.std() > 10                      # not a blank picture
    assert (np.abs(img - hair).sum(axis=2) < 120).sum() > 500   # hair-coloured pixels
    bad = subprocess.run([sys.executable, '-m', 'hair_sim.modeling', str(tmp_path / 'no.yaml')],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and 'cannot read' in bad.stderr


def test_preview_command_takes_a_shipped_style_by_name(tmp_path):
    """
    `python -m hair_sim.modeling thesis_long`, as the node and the demo take a style.

    An installed copy has no config/ in the working folder; the name gave "hairstyle file
    thesis_long: cannot read it". A file of that name in the working folder still wins.
    """
    out = subprocess.run([sys.executable, '-m', 'hair_sim.modeling', 'thesis_long'],
                         capture_output=True, text=True, timeout=120, cwd=str(tmp_path))
    assert out.returncode == 0, out.stderr
    strips = build_strips(load_hairstyle(paths.shipped_style('thesis_long')))
    assert out.stdout.startswith('thesis_long: ') and \
        '%d strips' % strips.n_strips in out.stdout, out.stdout
    (tmp_path / 'thesis_long').write_text('not: [a style')
    mine = subprocess.run([sys.executable, '-m', 'hair_sim.modeling', 'thesis_long'],
                          capture_output=True, text=True, timeout=60, cwd=str(tmp_path))
    assert mine.returncode == 2, mine.stdout
    assert 'hairstyle file %s: not valid YAML' % (tmp_path / 'thesis_long') in mine.stderr, \
        mine.stderr


@pytest.mark.parametrize('flag', ['--export', '--png'])
def test_preview_command_says_where_it_cannot_write_in_one_line(tmp_path, flag):
    """
    An output in a missing folder, on a folder, or with no name: one line, exit 2.

    The OBJ export ended in a traceback (FileNotFoundError from the temporary file), and
    the PNG made the missing folder and wrote into it.
    """
    def run(out):
        return subprocess.run([sys.executable, '-m', 'hair_sim.modeling',
                               paths.shipped_style('bob_fringe'), flag, out],
                              capture_output=True, text=True, timeout=120)

    missing = tmp_path / 'nope' / 'x.out'
    got = run(str(missing))
    assert got.returncode == 2, got.stderr
    assert got.stderr.strip() == 'error: %s cannot write into %s' % (flag, missing.parent)
    assert not missing.parent.exists()
    got = run(str(tmp_path))
    assert got.returncode == 2 and 'is a directory' in got.stderr, got.stderr
    got = run('')
    assert got.returncode == 2 and '%s needs a file name' % flag in got.stderr, got.stderr
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize('flag', ['--export', '--png'])
def test_preview_command_says_a_write_that_fails_in_one_line(tmp_path, flag, monkeypatch,
                                                             capsys):
    """A disk that fills while the preview writes: one line, exit 1, nothing left there."""
    import errno
    from hair_sim.modeling import __main__ as preview

    def full_disk(path, data, mode=0o644):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    for module in ('hair_sim.modeling.strips_over_head', 'hair_sim.fileio'):
        monkeypatch.setattr(sys.modules[module], 'write_atomic', full_disk)
    out = str(tmp_path / 'x.out')
    assert preview.main([paths.shipped_style('bob_fringe'), flag, out]) == 1
    err = capsys.readouterr().err
    assert err == 'error: could not write %s: No space left on device; nothing written ' \
        'there\n' % out, err
    assert os.listdir(tmp_path) == []
