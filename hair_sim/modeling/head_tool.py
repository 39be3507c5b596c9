"""
Bring your own head: fit collision spheres to a mesh, move hairstyles onto the new head.

    hair_sim_head fit MESH [--spheres 63] [--axes xyz] [--scale 1] [--out HEAD.yaml]
    hair_sim_head reroot STYLE.yaml HEAD.yaml [--out NEW_STYLE.yaml]

`fit` writes a head file next to the mesh (HEAD.yaml, default <mesh>.yaml) and the mesh as
<name>_display.glb beside it for the viewers, and prints the fit (surface-to-union distance
percentiles, mm) as JSON. `reroot` writes a derived style whose roots sit on the new scalp
(default <style>_on_<head>.yaml next to the head file). Nothing is overwritten without
--force; files are written atomically; a bad input is refused with the reason (exit 2).
"""

import argparse
import json
import os
import sys
import time

from hair_sim.fileio import files_as_they_are, put_files_back, unwritable_file
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.glb import GlbError


def fit_command(args):
    """Fit spheres to args.mesh; write the head file and its display mesh."""
    import numpy as np
    from hair_sim.modeling import head_fit
    from hair_sim.modeling import glb as glb_limits
    from hair_sim.modeling.glb import write_glb
    from hair_sim.modeling.head import load_head
    from hair_sim.modeling.yamlio import write_yaml_atomic
    stem = os.path.splitext(os.path.basename(args.mesh))[0]
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(os.path.abspath(args.mesh)),
                                                   stem + '.yaml'))
    name = os.path.splitext(os.path.basename(out))[0]
    glb = os.path.join(os.path.dirname(out), name + '_display.glb')
    for path in (out, glb):
        why = unwritable_file(path)
        if why:
            raise HairstyleError(why)
        if os.path.exists(path) and not args.force:
            raise HairstyleError('%s exists (use --force to replace it)' % path)
    t0 = time.perf_counter()
    vertices, triangles = head_fit.load_mesh(args.mesh, args.axes, args.scale)
    spheres, samples, above, top = head_fit.fit_spheres(vertices, triangles, args.spheres)
    # the viewers read the display mesh with the package's small GLB reader: one it would
    # refuse is not written (the head is then drawn as its spheres) and the report says so
    size = 12 * len(vertices) + 12 * len(triangles) + 1024
    drawable = len(vertices) <= glb_limits.MAX_VERTICES and size <= glb_limits.MAX_BYTES
    head = head_fit.head_from_spheres(spheres, top, name,
                                      os.path.basename(glb) if drawable else '')
    report = head_fit.fit_report(spheres, samples, above, time.perf_counter() - t0)
    if not drawable:
        report['display_mesh_skipped'] = (
            '%d vertices, %d triangles: over what the viewers read (%d vertices, %d MiB); '
            'decimate the mesh and fit again to draw it' % (
                len(vertices), len(triangles), glb_limits.MAX_VERTICES,
                glb_limits.MAX_BYTES >> 20))
    # the head file and its display mesh together, or neither: on any failure (a write, or
    # the check that they load back) both are put back as they were
    before = files_as_they_are([glb, out] if drawable else [out])
    try:
        if drawable:
            write_glb(glb, vertices.astype(np.float32), triangles.astype(np.uint32))
        write_yaml_atomic(out, head)
        loaded = load_head(out)          # what the node will read: it must load back
        if drawable:
            loaded.display_mesh()        # and its display mesh too
    except OSError as exc:
        put_files_back(before)
        raise HairstyleError('cannot write %s (and its display mesh): %s'
                             % (out, exc.strerror or exc)) from None
    except BaseException:
        put_files_back(before)
        raise
    report.update({'head': out, 'display_mesh': glb if drawable else None,
                   'scalp_spheres': len(loaded.scalp), 'body_spheres': len(loaded.body)})
    print(json.dumps(report, indent=1))
    return 0


def reroot_command(args):
    """Move a style onto a head file; write the derived style."""
    from hair_sim.modeling.reroot import reroot_file
    out, style = reroot_file(args.style, args.head, args.out, args.force)
    print('wrote %s: %d patches, %d strips on head %s'
          % (out, len(style.patches), style.n_strips, style.head.name))
    return 0


def main(argv=None):
    """Run `fit` or `reroot`; exit 2 with the reason on a bad input."""
    parser = argparse.ArgumentParser(prog='hair_sim_head', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    fit = sub.add_parser('fit', help='fit collision spheres to a head mesh')
    fit.add_argument('mesh', help='OBJ, GLB/glTF, STL or PLY in the head frame')
    fit.add_argument('--spheres', type=int, default=63, help='spheres in all (1-63)')
    fit.add_argument('--axes', default='xyz',
                     help='mesh axes giving the head frame x, y, z, e.g. "z,x,y" for y-up '
                          'glTF facing +z (default xyz)')
    fit.add_argument('--scale', type=float, default=1.0, help='metres per mesh unit')
    fit.add_argument('--out', help='head file to write (default: next to the mesh)')
    fit.add_argument('--force', action='store_true', help='replace existing files')
    rr = sub.add_parser('reroot', help='move a hairstyle onto another head')
    rr.add_argument('style', help='hairstyle YAML')
    rr.add_argument('head', help='head YAML (e.g. written by fit)')
    rr.add_argument('--out', help='style file to write (default: next to the head file)')
    rr.add_argument('--force', action='store_true', help='replace an existing file')
    args = parser.parse_args(argv)
    from hair_sim.modeling.head_fit import FitError
    try:
        if args.command == 'fit':
            return fit_command(args)
        return reroot_command(args)
    except (HairstyleError, FitError, GlbError, OSError) as exc:
        print('error: %s' % exc, file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
