"""
Look at a hairstyle without ROS.

    python -m hair_sim.modeling STYLE.yaml [--export out.obj] [--png out.png]
"""

import argparse
import sys

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import load_hairstyle
from hair_sim.modeling.strips_over_head import export_obj, render_png
from hair_sim.modeling.strips import build_strips


def main(argv=None):
    """Load a style, print its counts, optionally write an OBJ and a PNG preview."""
    parser = argparse.ArgumentParser(prog='python -m hair_sim.modeling', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('style', help='hairstyle YAML file')
    parser.add_argument('--export', metavar='OUT.obj', help='write the strips as an OBJ file')
    parser.add_argument('--png', metavar='OUT.png', help='render front/side/back views')
    args = parser.parse_args(argv)
    try:
        style = load_hairstyle(args.style)
    except HairstyleError as exc:
        print('error: %s' % exc, file=sys.stderr)
        return 2
    strips = build_strips(style)
    print('%s: %d patches, %d strips, %d strands x %d vertices (head %s)'
          % (style.name, len(style.patches), strips.n_strips, strips.n_strands,
             strips.n_vertices, style.head.name))
    if args.export:
        print('wrote %s' % export_obj(style, args.export))
    if args.png:
        print('wrote %s' % render_png(style, args.png))
    return 0


if __name__ == '__main__':
    sys.exit(main())
