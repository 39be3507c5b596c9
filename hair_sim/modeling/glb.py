"""
The smallest binary glTF 2.0 (GLB) the package needs: one triangle mesh, positions and indices.

Shipped head meshes are written by tools/make_head_mesh.py and read here without any mesh
library; a file that is not such a GLB is refused with a short reason.
"""

import json
import struct

import numpy as np

from hair_sim.fileio import read_regular_file, write_atomic

MAGIC = 0x46546C67          # 'glTF'
JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942
MAX_BYTES = 8 << 20         # a head mesh is ~200 KB
MAX_VERTICES = 200000


class GlbError(ValueError):
    """A file is not a GLB this reader takes."""


def write_glb(path, vertices, triangles):
    """Write float32 vertices (n, 3) and uint32 triangles (m, 3) as a GLB, atomically."""
    v = np.ascontiguousarray(vertices, dtype='<f4')
    t = np.ascontiguousarray(triangles, dtype='<u4')
    vb, tb = v.tobytes(), t.tobytes()
    gltf = {
        'asset': {'version': '2.0', 'generator': 'hair_sim'},
        'scene': 0, 'scenes': [{'nodes': [0]}], 'nodes': [{'mesh': 0}],
        'meshes': [{'primitives': [{'attributes': {'POSITION': 0}, 'indices': 1}]}],
        'buffers': [{'byteLength': len(vb) + len(tb)}],
        'bufferViews': [{'buffer': 0, 'byteOffset': 0, 'byteLength': len(vb), 'target': 34962},
                        {'buffer': 0, 'byteOffset': len(vb), 'byteLength': len(tb),
                         'target': 34963}],
        'accessors': [{'bufferView': 0, 'componentType': 5126, 'count': len(v), 'type': 'VEC3',
                       'min': v.min(axis=0).tolist(), 'max': v.max(axis=0).tolist()},
                      {'bufferView': 1, 'componentType': 5125, 'count': t.size,
                       'type': 'SCALAR'}],
    }
    js = json.dumps(gltf, separators=(',', ':')).encode()
    js += b' ' * (-len(js) % 4)
    binary = vb + tb
    binary += b'\0' * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    data = (struct.pack('<III', MAGIC, 2, total) + struct.pack('<II', len(js), JSON_CHUNK) + js
            + struct.pack('<II', len(binary), BIN_CHUNK) + binary)
    return write_atomic(path, data)


def read_glb(path):
    """Return (vertices (n, 3) float64, triangles (m, 3) int64) of a GLB written as above."""
    data = read_regular_file(path, MAX_BYTES)
    if len(data) > MAX_BYTES:
        raise GlbError('larger than %d MiB' % (MAX_BYTES >> 20))
    try:
        magic, version, total = struct.unpack_from('<III', data, 0)
        if magic != MAGIC or version != 2 or total != len(data):
            raise GlbError('not a glTF 2.0 binary')
        jlen, jtype = struct.unpack_from('<II', data, 12)
        gltf = json.loads(data[20:20 + jlen])
        blen, btype = struct.unpack_from('<II', data, 20 + jlen)
        if jtype != JSON_CHUNK or btype != BIN_CHUNK:
            raise GlbError('chunks out of order')
        binary = data[28 + jlen:28 + jlen + blen]
        prim = gltf['meshes'][0]['primitives'][0]
        pos = gltf['accessors'][prim['attributes']['POSITION']]
        idx = gltf['accessors'][prim['indices']]

        def view(acc, dtype, width):
            bv = gltf['bufferViews'][acc['bufferView']]
            start = bv.get('byteOffset', 0) + acc.get('byteOffset', 0)
            n = int(acc['count']) * width
            if n <= 0 or start < 0 or start + n * np.dtype(dtype).itemsize > len(binary):
                raise GlbError('an accessor runs past the buffer')
            return np.frombuffer(binary, dtype=dtype, count=n, offset=start)
        if pos['componentType'] != 5126 or pos['type'] != 'VEC3':
            raise GlbError('positions must be float32 VEC3')
        if idx['componentType'] not in (5125, 5123):
            raise GlbError('indices must be uint32 or uint16')
        v = view(pos, '<f4', 3).reshape(-1, 3).astype(np.float64)
        t = view(idx, '<u4' if idx['componentType'] == 5125 else '<u2', 1)
    # (a count of Infinity or 1e400 in the JSON raised OverflowError, JSON nested 100000
    # deep RecursionError: the load of a style with such a head failed as "internal error")
    except (struct.error, KeyError, IndexError, TypeError, ValueError, OverflowError,
            RecursionError) as exc:
        if isinstance(exc, GlbError):
            raise
        raise GlbError('not a mesh this reader takes (%s)' % type(exc).__name__) from None
    if len(v) > MAX_VERTICES or t.size % 3 or (t.size and t.max() >= len(v)):
        raise GlbError('indices out of range or too many vertices')
    if not np.all(np.isfinite(v)):
        raise GlbError('non-finite positions')
    return v, t.reshape(-1, 3).astype(np.int64)
