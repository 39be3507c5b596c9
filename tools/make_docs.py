"""
Regenerate the pictures in doc/ from the shipped styles.

Run from the repository root: .venv/bin/python tools/make_docs.py
"""

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths  # noqa: E402
from hair_sim.modeling.strips_over_head import render_png  # noqa: E402
from hair_sim.render.raycast_views import views_png  # noqa: E402
from hair_sim.sinks.meshcat_sink import screenshot  # noqa: E402


def main():
    """Write doc/style_<name>.png for every shipped style and doc/ushape_views.png."""
    doc = os.path.join(ROOT, 'doc')
    os.makedirs(doc, exist_ok=True)
    for name in paths.shipped_style_names():
        path = paths.shipped_style(name)
        print(render_png(load_hairstyle(path), os.path.join(doc, 'style_%s.png' % name)))
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')))
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    while not sim.sleeping:
        sim.step(DEFAULT_DT)
    print(views_png(sim, os.path.join(doc, 'ushape_views.png')))
    print(meshcat_png(os.path.join(doc, 'meshcat.png')))
    print(meshcat_png(os.path.join(doc, 'meshcat_front.png'), view='front'))


def meshcat_png(path, view='three_quarter'):
    """Run the demo, screenshot its meshcat page with headless Chromium, stop the demo."""
    import subprocess
    import time
    demo = subprocess.Popen([os.path.join(os.path.dirname(sys.executable), 'hair_sim_demo'),
                             '--duration', '60', '--ros-args', '-p', 'meshcat.view:=' + view],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    try:
        url = None
        for line in demo.stdout:
            if line.startswith('URL '):
                url = line.split()[1]
                break
        time.sleep(4.0)
        return screenshot(url, path)
    finally:
        demo.terminate()
        demo.wait(timeout=20)


if __name__ == '__main__':
    main()
