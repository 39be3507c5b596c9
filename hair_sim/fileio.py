"""Atomic file writes: a temporary file in the same directory, fsync, rename, fsync the dir."""

import os
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


def save_figure(fig, path, dpi=100):
    """Save a matplotlib figure as a PNG, atomically."""
    import io
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=dpi, bbox_inches='tight')
    return write_atomic(path, buf.getvalue())
