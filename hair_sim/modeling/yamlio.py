"""
Hostile-proof YAML reading and atomic YAML writing for head and hairstyle files.

Files come from users and pipelines, so nothing is built before it is checked. The reader
walks libyaml's event stream (C parser) and builds plain Python values itself:

- files over MAX_FILE_BYTES are refused before they are read;
- anything but a regular file (a FIFO, a device) is refused when opened, without waiting;
- aliases share the anchored value (nothing is copied), and the size the document would
  have with every alias expanded is counted as it streams: past MAX_NODES (an alias bomb)
  it is refused, as are aliases to an enclosing node, explicit tags (nothing is constructed
  but mappings, sequences, strings and numbers) and documents after the first;
- nesting deeper than MAX_DEPTH and scalars longer than MAX_SCALAR are refused while
  streaming, so no recursion and no quadratic number parsing can happen;
- plain scalars resolve by the YAML 1.2 core schema (null, true/false, integers, floats
  with or without a dot); quoted scalars stay strings; duplicate keys are refused.

Every problem is a short HairstyleError naming the file; none echoes the document.
"""

import os
import re

import yaml

from hair_sim.fileio import read_regular_file, write_atomic
from hair_sim.modeling.errors import HairstyleError

# The largest shipped style is 14 KB; a style at the vertex budget needs under 200 KB.
MAX_FILE_BYTES = 1024 * 1024
MAX_DEPTH = 10                # a style nests 6 deep (patches/hair/point/coordinate)
MAX_SCALAR = 1024             # characters in one scalar
MAX_MESSAGE = 200             # characters of a parser message kept in an error
MAX_NODES = 500000            # values in the document with aliases expanded (a style at the
#                               control point limit has about 70 000)

_INT = re.compile(r'[-+]?[0-9]+\Z')
_HEX = re.compile(r'0x[0-9a-fA-F]+\Z')
_OCT = re.compile(r'0o[0-7]+\Z')
_FLOAT = re.compile(r'[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?\Z')
_SPECIAL = {'~': None, 'null': None, 'Null': None, 'NULL': None, '': None,
            'true': True, 'True': True, 'TRUE': True,
            'false': False, 'False': False, 'FALSE': False,
            '.inf': float('inf'), '.Inf': float('inf'), '.INF': float('inf'),
            '+.inf': float('inf'), '+.Inf': float('inf'), '+.INF': float('inf'),
            '-.inf': float('-inf'), '-.Inf': float('-inf'), '-.INF': float('-inf'),
            '.nan': float('nan'), '.NaN': float('nan'), '.NAN': float('nan')}


def short(value, limit=60):
    """Return repr(value) cut to `limit` characters, for error messages."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + '...'


def _resolve(text):
    """Return the value of a plain scalar (YAML 1.2 core schema)."""
    if text in _SPECIAL:
        return _SPECIAL[text]
    if _INT.match(text):
        return int(text)
    if _HEX.match(text):
        return int(text[2:], 16)
    if _OCT.match(text):
        return int(text[2:], 8)
    if _FLOAT.match(text):
        return float(text)
    return text


class _Builder:
    """Build plain values from parser events, refusing what a head or style never needs."""

    def __init__(self, what):
        self.what = what
        self.stack = []            # open containers
        self.keys = []             # pending key of each open mapping (None: expecting one)
        self.sizes = []            # expanded size of each open container so far
        self.open_anchors = []     # anchor of each open container (or None)
        self.anchors = {}          # anchor -> (value, expanded size) of closed nodes
        self.total = 0             # values in the document with aliases expanded
        self.root = None
        self.documents = 0

    def fail(self, why):
        raise HairstyleError('%s: not valid YAML here (%s)' % (self.what, why))

    def count(self, n):
        self.total += n
        if self.total > MAX_NODES:
            self.fail('over %d values with aliases expanded' % MAX_NODES)
        if self.sizes:
            self.sizes[-1] += n

    def add(self, value):
        if not self.stack:
            self.root = value
            return
        top = self.stack[-1]
        if isinstance(top, list):
            top.append(value)
            return
        key = self.keys[-1]
        if key is None:
            if not isinstance(value, (str, int, float)) or isinstance(value, bool):
                self.fail('mapping keys must be plain strings or numbers')
            if value in top:
                self.fail('duplicate key %s' % short(value))
            self.keys[-1] = value
        else:
            top[key] = value
            self.keys[-1] = None

    def event(self, ev):
        kind = type(ev)
        if kind is yaml.AliasEvent:
            if ev.anchor not in self.anchors:
                self.fail('alias *%s refers to no finished anchor' % short(ev.anchor, 30))
            value, size = self.anchors[ev.anchor]
            self.count(size)
            self.add(value)
        elif kind is yaml.ScalarEvent:
            if ev.tag is not None and not any(ev.implicit):
                self.fail('tags (!!...) are not allowed')
            if len(ev.value) > MAX_SCALAR:
                self.fail('a value of %d characters is longer than %d'
                          % (len(ev.value), MAX_SCALAR))
            value = _resolve(ev.value) if not ev.style else ev.value
            self.count(1)
            self.add(value)
            if ev.anchor is not None:
                self.anchors[ev.anchor] = (value, 1)
        elif kind is yaml.SequenceStartEvent or kind is yaml.MappingStartEvent:
            if ev.tag is not None and not ev.implicit:
                self.fail('tags (!!...) are not allowed')
            if len(self.stack) >= MAX_DEPTH:
                self.fail('nested deeper than %d levels' % MAX_DEPTH)
            if self.stack and isinstance(self.stack[-1], dict) and self.keys[-1] is None:
                self.fail('mapping keys must be plain strings or numbers')
            box = [] if kind is yaml.SequenceStartEvent else {}
            self.add(box)
            self.stack.append(box)
            self.keys.append(None)
            self.sizes.append(1)
            self.open_anchors.append(ev.anchor)
            self.total += 1
        elif kind is yaml.SequenceEndEvent or kind is yaml.MappingEndEvent:
            box = self.stack.pop()
            self.keys.pop()
            size = self.sizes.pop()
            anchor = self.open_anchors.pop()
            if self.sizes:
                self.sizes[-1] += size
            if anchor is not None:
                self.anchors[anchor] = (box, size)
        elif kind is yaml.DocumentStartEvent:
            self.documents += 1
            if self.documents > 1:
                self.fail('only one YAML document is allowed')


def parse_yaml(text, what):
    """Return the plain value of YAML `text`; raise HairstyleError (prefixed `what`) if bad."""
    builder = _Builder(what)
    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
    try:
        for ev in yaml.parse(text, Loader=loader):
            builder.event(ev)
    except yaml.YAMLError as exc:
        problem = getattr(exc, 'problem', None) or str(exc).split('\n')[0]
        mark = getattr(exc, 'problem_mark', None)
        where = ' at line %d, column %d' % (mark.line + 1, mark.column + 1) if mark else ''
        raise HairstyleError('%s: not valid YAML (%s%s)'
                             % (what, str(problem)[:MAX_MESSAGE], where)) from None
    except RecursionError:
        raise HairstyleError('%s: nested too deeply' % what) from None
    return builder.root


def read_yaml(path, what):
    """Read and parse the YAML file at `path`; its top level must be a mapping."""
    label = '%s file %s' % (what, path)
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise HairstyleError('%s: cannot read it (%s)' % (label, exc.strerror)) from None
    if size > MAX_FILE_BYTES:
        raise HairstyleError('%s: %d bytes is over the %d byte limit'
                             % (label, size, MAX_FILE_BYTES))
    try:
        raw = read_regular_file(path, MAX_FILE_BYTES)
        text = raw.decode('utf-8')
    except OSError as exc:
        raise HairstyleError('%s: cannot read it (%s)' % (label, exc.strerror)) from None
    except UnicodeDecodeError:
        raise HairstyleError('%s: not UTF-8 text' % label) from None
    if len(raw) > MAX_FILE_BYTES:
        raise HairstyleError('%s: over the %d byte limit' % (label, MAX_FILE_BYTES))
    data = parse_yaml(text, label)
    if not isinstance(data, dict):
        raise HairstyleError('%s: the top level must be a mapping, not %s'
                             % (label, type(data).__name__))
    return data


class _Dumper(yaml.SafeDumper):
    """SafeDumper that quotes every string this reader would resolve to something else."""


def _represent_str(dumper, value):
    style = "'" if _resolve(value) is not value else None
    return dumper.represent_scalar('tag:yaml.org,2002:str', value, style=style)


_Dumper.add_representer(str, _represent_str)


def dump_yaml(data):
    """Return `data` as YAML text that parse_yaml reads back equal."""
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=None,
                     width=100)


def write_yaml_atomic(path, data):
    """Write `data` as YAML to `path` atomically (see hair_sim.fileio.write_atomic)."""
    return write_atomic(path, dump_yaml(data))
