"""A small little-endian CDR (XCDR1) writer: what rclpy serializes, written with numpy."""

import struct

import numpy as np

ENCAPSULATION = b'\x00\x01\x00\x00'        # CDR, little endian, no options


class CdrWriter:
    """
    Append CDR-encoded values; alignment is relative to the start of the payload.

    Padding is written as zeros and its byte ranges are kept in `padding`: CDR leaves
    their value open (rclpy's serializer does not clear them), so a comparison of two
    serializations must skip them.
    """

    def __init__(self):
        self.parts = [ENCAPSULATION]
        self.pos = 0
        self.padding = []

    def _align(self, n):
        pad = (-self.pos) % n
        if pad:
            self.parts.append(b'\x00' * pad)
            self.padding.append((len(ENCAPSULATION) + self.pos, pad))
            self.pos += pad

    def _raw(self, b):
        self.parts.append(b)
        self.pos += len(b)

    def prim(self, fmt, value):
        """Write one primitive (struct format like '<i', '<I', '<d', '<f', '<?')."""
        size = struct.calcsize(fmt)
        self._align(size)
        self._raw(struct.pack(fmt, value))

    def int32(self, v):
        """Write an int32."""
        self.prim('<i', v)

    def uint32(self, v):
        """Write a uint32."""
        self.prim('<I', v)

    def float64(self, v):
        """Write a float64."""
        self.prim('<d', v)

    def float32(self, v):
        """Write a float32."""
        self.prim('<f', v)

    def boolean(self, v):
        """Write a bool."""
        self.prim('<?', bool(v))

    def string(self, s):
        """Write a string: length with the terminating zero, bytes, zero."""
        b = s.encode('utf-8') + b'\x00'
        self.uint32(len(b))
        self._raw(b)

    def offset_of_next(self, align):
        """Return the byte offset (in the whole message) where a value of `align` goes next."""
        return len(ENCAPSULATION) + self.pos + (-self.pos) % align

    def array(self, arr, align):
        """
        Write a sequence: count, then the contiguous bytes; return the bytes' offset.

        The array's memory is joined into the message by bytes(), not copied here first
        (a frame's vertices are megabytes): leave it unchanged until then.
        """
        arr = np.ascontiguousarray(arr)
        self.uint32(len(arr))
        if len(arr):
            self._align(align)
        start = len(ENCAPSULATION) + self.pos
        if len(arr):
            self._raw(memoryview(arr).cast('B'))
        return start

    def octets(self, data):
        """Write a uint8[] sequence."""
        self.uint32(len(data))
        self._raw(bytes(data))

    def time(self, sec, nanosec):
        """Write a builtin_interfaces/Time or Duration."""
        self.int32(sec)
        self.uint32(nanosec)

    def header(self, sec, nanosec, frame_id):
        """Write a std_msgs/Header."""
        self.time(sec, nanosec)
        self.string(frame_id)

    def bytes(self):
        """Return the serialized message."""
        return b''.join(self.parts)


def same_bytes_but_padding(a, b, padding):
    """Return True if a and b are equal everywhere except in the padding ranges."""
    if len(a) != len(b):
        return False
    a, b = bytearray(a), bytearray(b)
    for start, n in padding:
        a[start:start + n] = b'\x00' * n
        b[start:start + n] = b'\x00' * n
    return a == b
