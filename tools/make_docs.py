"""
Regenerate the pictures in doc/ from the shipped styles.

Run from the repository root: .venv/bin/python tools/make_docs.py
"""

import glob
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths  # noqa: E402
from hair_sim.modeling.preview import render_png  # noqa: E402
from hair_sim.render.preview import views_png  # noqa: E402


def main():
    """Write doc/style_<name>.png for every shipped style and doc/ushape_views.png."""
    doc = os.path.join(ROOT, 'doc')
    os.makedirs(doc, exist_ok=True)
    for path in sorted(glob.glob(os.path.join(paths.hairstyles_dir(), '*.yaml'))):
        name = os.path.basename(path)[:-5]
        print(render_png(load_hairstyle(path), os.path.join(doc, 'style_%s.png' % name)))
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')))
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    while not sim.sleeping:
        sim.step(DEFAULT_DT)
    print(views_png(sim, os.path.join(doc, 'ushape_views.png')))


if __name__ == '__main__':
    main()
