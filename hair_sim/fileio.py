"""Atomic file writes: a temporary file in the same directory, fsync, rename, fsync the dir."""

import errno
import os
import stat
import tempfile


def write_atomic(path, data, mode=0o644):
    """
    Write `data` (bytes or str) to `path` so that readers see the old file or the new one.

    A crash or a kill at any moment leaves either the previous file intact or the complete
    new one, never a truncated mix; the temporary file is removed on any error.
    """
    if isinstance(data, str):
        data = data.encode('utf-8')
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix='.' + os.path.basename(path) + '.', suffix='.tmp',
                               dir=directory)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, 'wb') as f:
            f.write(data)
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
    return path


def read_regular_file(path, max_bytes):
    """
    Return the first max_bytes + 1 bytes of the regular file at `path` (more: too large).

    The file is opened without waiting and checked on its open descriptor: a FIFO, whose
    open and read wait for a writer for ever, or a device is refused with an OSError ("not
    a regular file"), also one put in place of a file that a check by name accepted.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EINVAL, 'not a regular file', path)
        os.set_blocking(fd, True)
        with os.fdopen(fd, 'rb') as f:
            fd = None
            return f.read(max_bytes + 1)
    finally:
        if fd is not None:
            os.close(fd)


def unwritable_file(path):
    """Return why a file cannot be written at `path` (no name, a folder or a FIFO there...)."""
    if not path:
        return 'needs a file name'
    if os.path.isdir(path):
        return '%s is a directory, not a file to write' % path
    if os.path.exists(path) and not os.path.isfile(path):
        return '%s is not a regular file (a FIFO or a device)' % path
    folder = os.path.dirname(os.path.abspath(path))
    if not (os.path.isdir(folder) and os.access(folder, os.W_OK | os.X_OK)):
        return 'cannot write into %s' % folder
    return None


def files_as_they_are(paths):
    """Return {path: its bytes, or None where there is no file}, to put back on failure."""
    out = {}
    for path in paths:
        try:
            with open(path, 'rb') as f:
                out[path] = f.read()
        except FileNotFoundError:
            out[path] = None
    return out


def put_files_back(saved):
    """
    Put files back as files_as_they_are found them: rewritten atomically, or removed.

    For writes of several files that belong together (a head file and its display mesh):
    when one of them, or the check after, fails, none is left changed.
    """
    for path, data in saved.items():
        try:
            if data is None:
                if os.path.lexists(path):
                    os.unlink(path)
            else:
                write_atomic(path, data)
        except OSError:
            pass


def save_figure(fig, path, dpi=100):
    """Save a matplotlib figure as a PNG, atomically."""
    import io
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=dpi, bbox_inches='tight')
    return write_atomic(path, buf.getvalue())
