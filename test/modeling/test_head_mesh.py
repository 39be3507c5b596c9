"""The shipped head mesh: where it sits against the spheres, and what the GLB reader refuses."""

import os
import struct
import threading

import numpy as np
import pytest

from hair_sim import load_head, paths
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.glb import GlbError, read_glb, write_glb
from helpers.glb_bytes import glb_json, glb_with_json
from hair_sim.modeling.yamlio import read_yaml


@pytest.fixture(scope='module')
def head():
    return load_head(paths.shipped_head('default_adult'))


def test_shipped_mesh_sits_just_inside_the_scalp(head):
    """Every skin vertex above the head frame's origin is inside the scalp spheres' union."""
    v, t = head.display_mesh()
    assert len(t) > 5000 and t.max() < len(v)
    above = v[v[:, 2] > 0.0]
    assert len(above) > 100
    assert head.scalp_distance(above).max() < 0.0
    # and it is the head's size, not a doll's: the cranium's length is about 0.19 m
    cranium = v[v[:, 2] > v[:, 2].max() - 0.1]
    assert 0.16 < np.ptp(cranium[:, 0]) < 0.20
    # the face points forward (+x): the nose tip, on the mid-plane below the scalp, leads
    nose = v[np.argmax(v[:, 0])]
    assert nose[0] > 0.09 and abs(nose[1]) < 0.005 and -0.12 < nose[2] < 0.0


def test_glb_round_trip_and_hostile_files(tmp_path):
    """What write_glb writes reads back; broken or hostile files are refused with GlbError."""
    v = np.random.default_rng(0).random((10, 3)).astype(np.float32)
    t = np.array([[0, 1, 2], [2, 3, 4]], dtype=np.uint32)
    good = tmp_path / 'good.glb'
    write_glb(str(good), v, t)
    rv, rt = read_glb(str(good))
    assert np.array_equal(rv, v.astype(float)) and np.array_equal(rt, t)
    data = good.read_bytes()
    cases = {'truncated': data[:-40], 'magic': b'xxxx' + data[4:], 'empty': b'',
             'length': data[:8] + struct.pack('<I', len(data) + 4) + data[12:]}
    bad_index = tmp_path / 'index.glb'
    write_glb(str(bad_index), v, np.array([[0, 1, 99]], dtype=np.uint32))
    cases['index'] = bad_index.read_bytes()
    nan = v.copy()
    nan[3, 1] = np.nan
    write_glb(str(tmp_path / 'nan.glb'), nan, t)
    cases['nan'] = (tmp_path / 'nan.glb').read_bytes()
    # (these two raised OverflowError and RecursionError, which no reader caught)
    for count in ('Infinity', '-Infinity', '1e400'):
        cases['count ' + count] = glb_with_json(glb_json(data).replace(
            b'"count":10', b'"count":' + count.encode(), 1))
        assert cases['count ' + count] != glb_with_json(glb_json(data))
    cases['deep json'] = glb_with_json(b'[' * 100000 + b']' * 100000)
    for name, blob in cases.items():
        path = tmp_path / (name + '.glb')
        path.write_bytes(blob)
        with pytest.raises(GlbError):
            read_glb(str(path))


@pytest.mark.parametrize('mesh', ['../default_adult_head.glb', '/etc/passwd.glb', 'head.obj',
                                  '.hidden.glb', 'sub/head.glb'])
def test_a_head_file_names_only_a_glb_next_to_it(tmp_path, mesh):
    """The head's `mesh:` is a .glb file name in the head file's folder, nothing else."""
    text = open(paths.shipped_head('default_adult')).read().replace(
        'mesh: default_adult_head.glb', 'mesh: %r' % mesh)
    f = tmp_path / 'h.yaml'
    f.write_text(text)
    with pytest.raises(HairstyleError, match='mesh'):
        load_head(str(f))


def _read_within(read, fifo, seconds=10.0):
    """Return what read() raised; fail if it still waits after `seconds` (a FIFO's open)."""
    box = {}

    def run():
        try:
            box['value'] = read()
        except Exception as exc:                     # noqa: B902
            box['error'] = exc
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))    # let it go: end of file
        thread.join(5.0)
        pytest.fail('still waiting for a writer after %.0f s' % seconds)
    return box.get('error')


def test_a_fifo_a_device_or_a_symlink_out_is_refused_at_once(tmp_path):
    """A head's mesh or file that is no regular file here is refused without waiting."""
    text = open(paths.shipped_head('default_adult')).read()
    shipped = os.path.join(os.path.dirname(paths.shipped_head('default_adult')),
                           'default_adult_head.glb')
    outside = tmp_path / 'outside'
    outside.mkdir()
    (outside / 'real.glb').write_bytes(open(shipped, 'rb').read())
    heads = tmp_path / 'heads'
    heads.mkdir()
    fifo = heads / 'fifo.glb'
    os.mkfifo(fifo)
    os.symlink('/dev/zero', heads / 'device.glb')
    os.symlink(fifo, heads / 'to_fifo.glb')
    os.symlink(outside / 'real.glb', heads / 'out.glb')
    os.symlink(outside / 'real.glb', outside / 'in.glb')
    expected = {'fifo.glb': 'not a regular file', 'to_fifo.glb': 'not a regular file',
                'device.glb': 'leads out of', 'out.glb': 'leads out of'}
    for mesh, fragment in expected.items():
        f = heads / (mesh + '.yaml')
        f.write_text(text.replace('default_adult_head.glb', mesh))
        head = load_head(str(f))
        error = _read_within(head.display_mesh, fifo)
        assert isinstance(error, (OSError, GlbError)) and fragment in str(error), (mesh, error)
    # a symlink within the folder is a file there
    f = outside / 'h.yaml'
    f.write_text(text.replace('default_adult_head.glb', 'in.glb'))
    v, t = load_head(str(f)).display_mesh()
    assert len(t) > 5000
    # the head (or style) file itself: a FIFO in its place, after a check by name passed
    os.mkfifo(tmp_path / 'h.yaml')
    error = _read_within(lambda: read_yaml(str(tmp_path / 'h.yaml'), 'head'),
                         tmp_path / 'h.yaml')
    assert isinstance(error, HairstyleError) and 'not a regular file' in str(error), error


def test_the_display_mesh_is_read_once_and_shared_read_only(monkeypatch, tmp_path):
    """Load once, display per frame: one read per head, its error kept as well."""
    from hair_sim.modeling import glb
    reads = []
    read_glb = glb.read_glb

    def counting(path):
        reads.append(path)
        return read_glb(path)
    monkeypatch.setattr(glb, 'read_glb', counting)
    head = load_head(paths.shipped_head('default_adult'))
    first, again = head.display_mesh(), head.display_mesh()
    assert len(reads) == 1 and first[0] is again[0] and first[1] is again[1]
    with pytest.raises(ValueError):
        first[0][0, 0] = 1.0                      # shared: nobody may change it
    assert load_head(paths.shipped_head('default_adult')).display_mesh() is not first
    assert len(reads) == 2                        # a head loaded again reads its file again
    text = open(paths.shipped_head('default_adult')).read()
    (tmp_path / 'h.yaml').write_text(text.replace('default_adult_head.glb', 'gone.glb'))
    broken = load_head(str(tmp_path / 'h.yaml'))
    for _ in range(2):
        with pytest.raises(OSError):
            broken.display_mesh()
    assert len(reads) == 3
