"""
The numbers a caller hands the simulator, checked before anything changes.

numpy converts more than numbers: np.array(x, dtype=np.float64) drops the imaginary part of
a complex value (with a warning only), reads the strings '1' and '0.5', and np.array(x,
dtype=np.int64) cuts 1.5 to 1. Each of these is a caller's mistake the simulator would
then run with; here they are refused.
"""

import math
import numbers

import numpy as np


def real_array(value, shape, what):
    """
    Return value as a new float64 array of `shape`, or raise ValueError naming `what`.

    It must be integers or floats (no flags, strings, complex or objects) of that shape.

    Shaped as in reshape (a -1 takes any length there); None keeps value's shape.
    """
    a = _array(value, what)
    if a.dtype.kind not in 'iuf':
        raise ValueError('%s must be real numbers, not %s' % (what, _kind(a)))
    if a.dtype != np.float64:
        a = a.astype(np.float64)
    if shape is None:
        return a
    try:
        return a.reshape(shape)
    except ValueError:
        raise ValueError('%s must be shaped %s, not %s'
                         % (what, shape, a.shape)) from None


def index_array(value, shape, what):
    """Return value as a new int64 array of `shape`; raise ValueError unless it is integers."""
    a = _array(value, what)
    if a.dtype.kind == 'f' and a.size and np.all(np.isfinite(a)) and np.all(a == np.round(a)):
        a = a.astype(np.int64)          # (whole numbers written as floats: 3.0 is index 3)
    if a.dtype.kind not in 'iu' and a.size:
        raise ValueError('%s must be whole numbers, not %s' % (what, _kind(a)))
    try:
        return a.astype(np.int64).reshape(shape)
    except (ValueError, OverflowError):
        raise ValueError('%s must be shaped %s, not %s'
                         % (what, shape, a.shape)) from None


def shown(value, limit=80):
    """Return repr(value) for a message, cut to `limit` characters with '...' if longer."""
    try:
        text = repr(value)
    except ValueError:                  # an int of more than sys.get_int_max_str_digits()
        if not isinstance(value, int):  # (any other repr's own error is the caller's)
            raise
        return 'an int of %d bits' % value.bit_length()
    return text if len(text) <= limit else text[:limit - 3] + '...'


def real_number(value, what):
    """
    Return value as a float; raise ValueError unless it is an int or float (not a flag).

    An int past a float's range comes back as the infinity of its sign, which the caller's
    finiteness check refuses with its own reason (float() raised OverflowError: a step of
    10**400 s, a turbulence of 10**400 or a pose stamped so escaped as that, not refused).
    """
    if type(value) is float:            # (the common case, without the ABC's check)
        return value
    if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
        raise ValueError('%s must be a number, not %s' % (what, shown(value)))
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def integer(value, what):
    """Return value as an int; raise ValueError unless it is a whole number (not a flag)."""
    if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
        raise ValueError('%s must be a whole number, not %r' % (what, value))
    return int(value)


def _array(value, what):
    if isinstance(value, (str, bytes, bytearray)):
        raise ValueError('%s must be numbers, not %s' % (what, type(value).__name__))
    try:
        return np.array(value)            # (a copy: the caller's array stays theirs)
    except (TypeError, ValueError):       # ragged lists
        raise ValueError('%s must be numbers in a regular array' % what) from None


def _kind(a):
    return {'b': 'flags', 'c': 'complex numbers', 'U': 'strings', 'S': 'bytes',
            'O': 'objects'}.get(a.dtype.kind, 'values of type %s' % a.dtype)
