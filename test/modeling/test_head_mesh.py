"""The shipped head mesh: where it sits against the spheres, and what the GLB reader refuses."""

import struct

import numpy as np
import pytest

from hair_sim import load_head, paths
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.glb import GlbError, read_glb, write_glb


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
