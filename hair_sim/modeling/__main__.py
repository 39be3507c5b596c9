"""
Look at a hairstyle without ROS.

    python -m hair_sim.modeling STYLE.yaml [--export out.obj] [--png out.png]

STYLE may also be the name of a style in the package's hairstyle folder (thesis_long), as
the node and the demo take it: an installed copy has no config/ in the working folder.
"""

import argparse
import os
import sys

from hair_sim import paths
from hair_sim.fileio import unwritable_file
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import load_hairstyle
from hair_sim.modeling.strips_over_head import export_obj, render_png
from hair_sim.modeling.strips import build_strips


def main(argv=None):
    """Load a style, print its counts, optionally write an OBJ and a PNG preview."""
    parser = argparse.ArgumentParser(prog='python -m hair_sim.modeling', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('style', help='hairstyle YAML file, or the name of a shipped style')
    parser.add_argument('--export', metavar='OUT.obj', help='write the strips as an OBJ file')
    parser.add_argument('--png', metavar='OUT.png', help='render front/side/back views')
    args = parser.parse_args(argv)
    # where the outputs cannot go is said before anything is built (a missing folder
    # too: it is not made), and a write that fails all the same ends in one line
    for flag, path in (('--export', args.export), ('--png', args.png)):
        why = path is not None and unwritable_file(path)
        if why:
            print('error: %s %s' % (flag, why), file=sys.stderr)
            return 2
    path = args.style
    if not os.path.exists(path) and os.path.isfile(paths.shipped_style(path)):
        path = paths.shipped_style(path)
    try:
        style = load_hairstyle(path)
    except HairstyleError as exc:
        print('error: %s' % exc, file=sys.stderr)
        return 2
    strips = build_strips(style)
    print('%s: %d patches, %d strips, %d strands x %d vertices (head %s)'
          % (style.name, len(style.patches), strips.n_strips, strips.n_strands,
             strips.n_vertices, style.head.name))
    for path, write in ((args.export, export_obj), (args.png, render_png)):
        if path is None:
            continue
        try:
            print('wrote %s' % write(style, path))
        except OSError as exc:
            print('error: could not write %s: %s; nothing written there'
                  % (path, exc.strerror or exc), file=sys.stderr)
            return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
