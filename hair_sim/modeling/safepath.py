"""Resolve hairstyle paths from requests so that only the configured directories are touched."""

import os

from hair_sim import paths
from hair_sim.modeling.errors import HairstyleError


def allowed_dirs(dirs):
    """Return the real paths of the configured directories ('' is the shipped one)."""
    out = []
    for d in dirs or ['']:
        d = paths.hairstyles_dir() if d == '' else os.path.expanduser(d)
        out.append(os.path.realpath(d))
    return out


def resolve_style_path(request, dirs, must_exist):
    """
    Return the real path of `request` inside one of `dirs`, or raise HairstyleError.

    A request is a name ('thesis_long'), a relative path ('mine/long.yaml') or an absolute
    path inside a configured directory; .yaml is added to a name without it. '..'
    components, other absolute paths, symlinks leading out of their directory, control
    characters and file names that start with a dot (a path ending in '/') or are longer
    than 255 bytes are refused. A name that exists in a directory resolves there (the first
    such); a new file for a save goes to the first configured directory that is not the
    shipped one (the shipped one if alone).
    """
    if not isinstance(request, str) or not request.strip():
        raise HairstyleError('empty hairstyle path')
    if '\x00' in request or len(request) > 4096:
        raise HairstyleError('malformed hairstyle path')
    req = request.strip()
    if any(c < ' ' or c == '\x7f' for c in req):
        raise HairstyleError('path %r: control characters (a newline, a tab) are not allowed'
                             % request[:100])
    if not req.endswith('.yaml'):
        req += '.yaml'
    name = os.path.basename(req.replace('\\', '/'))
    if name.startswith('.'):
        # 'sub/' was saved as sub/.yaml and '.' as ..yaml: hidden files nobody asked for,
        # named as write_atomic's temporary files (.NAME.xxx.tmp) are
        raise HairstyleError('path %r: no file name (a hairstyle is NAME.yaml, NAME not '
                             'starting with a dot)' % request)
    if len(name.encode('utf-8', 'surrogatepass')) > 255:
        raise HairstyleError('path %r: its file name is longer than 255 bytes' % request[:100])
    if '..' in req.replace('\\', '/').split('/'):
        raise HairstyleError('path %r: ".." is not allowed' % request)
    roots = allowed_dirs(dirs)

    def inside(real, root):
        return os.path.commonpath([real, root]) == root

    if os.path.isabs(req):
        real = os.path.realpath(req)
        homes = [r for r in roots if inside(os.path.abspath(req), r)]
        if not homes or not inside(real, homes[0]):
            raise HairstyleError('path %r is outside the hairstyle directories' % request)
        candidates = [(homes[0], req)]
    else:
        candidates = [(r, os.path.join(r, req)) for r in roots]
    for root, cand in candidates:
        if os.path.lexists(cand):
            real = os.path.realpath(cand)
            if not inside(real, root):
                raise HairstyleError('path %r leads out of %s (symlink)' % (request, root))
            if must_exist and not os.path.isfile(real):
                raise HairstyleError('%r is not a file' % request)
            return real
    if must_exist:
        raise HairstyleError('no hairstyle %r in %s' % (request, ', '.join(roots)))
    shipped = os.path.realpath(paths.hairstyles_dir())
    root, cand = next(((r, c) for r, c in candidates if r != shipped), candidates[0])
    real = os.path.realpath(cand)
    if not inside(real, root) or not os.path.isdir(os.path.dirname(real)):
        raise HairstyleError('path %r: its directory is not inside the hairstyle directories'
                             % request)
    return real


def resolve_save_path(request, dirs, overwrite):
    """
    Return the real path a save of `request` writes (resolve_style_path), or raise.

    An existing file is refused unless `overwrite`, and a shipped hairstyle always: the
    package's styles are its data (tools/make_styles.py makes them), and a save over one
    replaced the default style of every later start (a careless client's save to
    'thesis_long' put another style in its place). A style a user saved beside them (the
    shipped directory is the only one by default) is the user's, and may be replaced.
    """
    path = resolve_style_path(request, dirs, must_exist=False)
    if not os.path.lexists(path):
        return path
    if path in {os.path.realpath(paths.shipped_style(n)) for n in paths.SHIPPED_STYLES}:
        raise HairstyleError('%r is a shipped hairstyle and is not replaced; save under '
                             'another name' % request)
    if not overwrite:
        raise HairstyleError('%r exists (set overwrite to replace it)' % request)
    return path
