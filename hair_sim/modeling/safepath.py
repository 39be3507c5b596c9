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
    path inside a configured directory. '..' components, other absolute paths, symlinks
    leading out of the directories and names not ending in .yaml are refused. For a save
    (must_exist False) the directory must exist; the file need not.
    """
    if not isinstance(request, str) or not request.strip():
        raise HairstyleError('empty hairstyle path')
    if '\x00' in request or len(request) > 4096:
        raise HairstyleError('malformed hairstyle path')
    req = request.strip()
    if not req.endswith('.yaml'):
        req += '.yaml'
    if '..' in req.replace('\\', '/').split('/'):
        raise HairstyleError('path %r: ".." is not allowed' % request)
    roots = allowed_dirs(dirs)
    candidates = [req] if os.path.isabs(req) else [os.path.join(r, req) for r in roots]
    for cand in candidates:
        real = os.path.realpath(cand)
        inside = [r for r in roots if os.path.commonpath([real, r]) == r]
        if not inside:
            continue
        if must_exist and not os.path.isfile(real):
            continue
        if not must_exist and not os.path.isdir(os.path.dirname(real)):
            continue
        return real
    if os.path.isabs(req) and not any(
            os.path.commonpath([os.path.realpath(req), r]) == r for r in roots):
        raise HairstyleError('path %r is outside the hairstyle directories' % request)
    if must_exist:
        raise HairstyleError('no hairstyle %r in %s' % (request, ', '.join(roots)))
    raise HairstyleError('path %r: its directory is not inside the hairstyle directories'
                         % request)
