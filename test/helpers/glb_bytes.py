"""GLB files written byte by byte, for readers' hostile cases."""

import struct

from hair_sim.modeling.glb import BIN_CHUNK, JSON_CHUNK, MAGIC


def glb_json(data):
    """Return the JSON chunk of GLB bytes."""
    (length,) = struct.unpack_from('<I', data, 12)
    return data[20:20 + length]


def glb_with_json(text, binary=b'\0' * 64):
    """Return GLB bytes of JSON chunk `text` (bytes, any content) and a binary chunk."""
    text += b' ' * (-len(text) % 4)
    return (struct.pack('<III', MAGIC, 2, 28 + len(text) + len(binary))
            + struct.pack('<II', len(text), JSON_CHUNK) + text
            + struct.pack('<II', len(binary), BIN_CHUNK) + binary)
