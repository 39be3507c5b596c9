"""Safe, size-limited YAML reading and atomic YAML writing."""

import os
import tempfile

import yaml

from hair_sim.modeling.errors import HairstyleError

# A hairstyle is a few hundred control points: anything this large is not one.
MAX_FILE_BYTES = 4 * 1024 * 1024


def read_yaml(path, what):
    """Parse `path` with yaml.safe_load; raise HairstyleError naming the file on any problem."""
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise HairstyleError('%s file %s: cannot read it (%s)' % (what, path, exc.strerror))
    if size > MAX_FILE_BYTES:
        raise HairstyleError('%s file %s: %d bytes is over the %d byte limit'
                             % (what, path, size, MAX_FILE_BYTES))
    try:
        with open(path, 'rb') as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as exc:
        raise HairstyleError('%s file %s: not valid YAML (%s)'
                             % (what, path, str(exc).replace('\n', ' ')))
    except (OSError, UnicodeDecodeError) as exc:
        raise HairstyleError('%s file %s: cannot read it (%s)' % (what, path, exc))
    if not isinstance(data, dict):
        raise HairstyleError('%s file %s: the top level must be a mapping, not %s'
                             % (what, path, type(data).__name__))
    return data


def write_yaml_atomic(path, data):
    """Write `data` as YAML to `path` through a temporary file, fsync and rename."""
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix='.' + os.path.basename(path) + '.', suffix='.tmp',
                               dir=directory)
    try:
        os.fchmod(fd, 0o644)
        with os.fdopen(fd, 'w') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    try:
        dfd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass
