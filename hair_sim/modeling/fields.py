"""
Checks for every field of a head or hairstyle file, applied where values enter.

Each helper takes the value as parsed (plain Python from `yamlio.parse_yaml`), its name
and `where` (file, patch, hair) for the message, and returns a clean value or raises a
short HairstyleError. Nothing here trusts a type: booleans are not numbers, strings are not
numbers, and integers of any size are compared before they are converted, so a 400-digit
number is "out of range", never an OverflowError.
"""

import math
import re

import numpy as np

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.yamlio import short

_FRAME = re.compile(r'[A-Za-z_][A-Za-z0-9_/]{0,99}\Z')


def _real(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and \
        not isinstance(value, (bool, np.bool_))


def require_mapping(value, name, where, allowed):
    """Return `value` if it is a mapping whose keys are all in `allowed`."""
    if not isinstance(value, dict):
        raise HairstyleError('%s: %s must be a mapping, not %s'
                             % (where, name, type(value).__name__))
    unknown = [k for k in value if k not in allowed]
    if unknown:
        raise HairstyleError('%s: unknown key(s) in %s: %s (known: %s)' % (
            where, name, ', '.join(short(k, 30) for k in unknown[:5]),
            ', '.join(sorted(allowed))))
    return value


def number(value, name, lo, hi, where):
    """Return `value` as a float if it is a finite real number in [lo, hi]."""
    if not _real(value):
        raise HairstyleError('%s: %s must be a number, not %s' % (where, name, short(value)))
    if isinstance(value, (int, np.integer)) and not -1e300 < value < 1e300:
        raise HairstyleError('%s: %s is outside [%g, %g]' % (where, name, lo, hi))
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi):
        raise HairstyleError('%s: %s = %s is outside [%g, %g]' % (where, name, short(v), lo, hi))
    return v


def integer(value, name, lo, hi, where):
    """Return `value` if it is a whole number in [lo, hi] (2.0 counts; 2.5 does not)."""
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        value = int(value)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise HairstyleError('%s: %s must be a whole number, not %s'
                             % (where, name, short(value)))
    if not lo <= value <= hi:
        raise HairstyleError('%s: %s = %s is outside [%d, %d]'
                             % (where, name, short(value, 30), lo, hi))
    return int(value)


def string(value, name, where, max_len=100, pattern=None):
    """Return `value` if it is a non-empty string of at most max_len printable characters."""
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise HairstyleError('%s: %s must be a string, not %s' % (where, name, short(value)))
    text = str(value)
    if not text or len(text) > max_len or not text.isprintable():
        raise HairstyleError('%s: %s must be 1 to %d printable characters'
                             % (where, name, max_len))
    if pattern is not None and not pattern.match(text):
        raise HairstyleError('%s: %s %s is not allowed' % (where, name, short(text)))
    return text


def frame_id(value, name, where):
    """Return a valid ROS frame name (letters, digits, '_' and '/', up to 100 characters)."""
    return string(value, name, where, 100, _FRAME)


def _shape_of(value, name, where, ndim):
    """Return the shape of a nested list of reals, checking every leaf's type."""
    shape = []
    level = [value]
    for depth in range(ndim):
        size = None
        nxt = []
        for item in level:
            if not isinstance(item, (list, tuple)):
                raise HairstyleError('%s: %s must be %d nested list(s) of numbers'
                                     % (where, name, ndim))
            if size is None:
                size = len(item)
            elif len(item) != size:
                raise HairstyleError('%s: %s has lists of different lengths (%d and %d)'
                                     % (where, name, size, len(item)))
            nxt.extend(item)
        shape.append(size or 0)
        level = nxt
    for leaf in level:
        if not _real(leaf):
            raise HairstyleError('%s: %s contains %s, not a number' % (where, name, short(leaf)))
    return tuple(shape)


def numeric_array(value, name, where, ndim, bound, shape=None):
    """
    Return a float64 array of nested lists `value` with `ndim` levels.

    Every leaf must be a real number with |x| <= bound; `shape`, if given, must match
    (None in it matches any length).
    """
    got = _shape_of(value, name, where, ndim)
    if shape is not None and any(w is not None and w != g for w, g in zip(shape, got)):
        want = 'x'.join('n' if w is None else str(w) for w in shape)
        raise HairstyleError('%s: %s must have shape %s, not %s'
                             % (where, name, want, 'x'.join(map(str, got))))
    for leaf in _leaves(value, ndim):
        if isinstance(leaf, (int, np.integer)) and not (-bound <= leaf <= bound
                                                        and -1e300 < leaf < 1e300):
            raise HairstyleError('%s: %s has a value over %g in size' % (where, name, bound))
    arr = np.array(value, dtype=np.float64).reshape(got)
    if not np.all(np.isfinite(arr)):
        raise HairstyleError('%s: %s contains a non-finite number (NaN or inf)' % (where, name))
    if arr.size and np.abs(arr).max() > bound:
        raise HairstyleError('%s: %s has a value over %g in size' % (where, name, bound))
    return arr


def _leaves(value, ndim):
    level = [value]
    for _ in range(ndim):
        level = [x for item in level for x in item]
    return level
