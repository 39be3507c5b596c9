"""Look at a hairstyle without ROS: OBJ export and a matplotlib PNG of strips over the head."""

import numpy as np

from hair_sim.fileio import save_figure, write_atomic
from hair_sim.modeling.strips import build_strips


def strip_quads(strips, positions=None):
    """Return the quads (n_strips * (V - 1), 4, 3) of the flat strips (rest or `positions`)."""
    pos = strips.rest if positions is None else positions
    a = pos[strips.strip_strands[:, 0]]
    b = pos[strips.strip_strands[:, 1]]
    quads = np.stack([a[:, :-1], b[:, :-1], b[:, 1:], a[:, 1:]], axis=2)
    return quads.reshape(-1, 4, 3)


def export_obj(style, path, positions=None):
    """Write the flat strips of `style` as a Wavefront OBJ (atomically) and return the path."""
    strips = build_strips(style)
    pos = strips.rest if positions is None else positions
    n_v = strips.n_vertices
    lines = ['# hair_sim hairstyle %s: %d strips, %d vertices per strand'
             % (style.name, strips.n_strips, n_v)]
    lines += ['v %.6f %.6f %.6f' % tuple(p) for p in pos.reshape(-1, 3)]
    for s, (ia, ib) in enumerate(strips.strip_strands):
        lines.append('g strip_%d' % s)
        for j in range(n_v - 1):
            a0, a1 = ia * n_v + j + 1, ia * n_v + j + 2
            b0, b1 = ib * n_v + j + 1, ib * n_v + j + 2
            lines.append('f %d %d %d %d' % (a0, b0, b1, a1))
    return write_atomic(path, ('\n'.join(lines) + '\n').encode())


def sphere_quads(spheres, n_u=24, n_v=12):
    """Return quads (n, 4, 3) approximating each sphere (cx, cy, cz, r), hidden parts dropped."""
    u = np.linspace(0, 2 * np.pi, n_u + 1)
    v = np.linspace(0, np.pi, n_v + 1)
    uu, vv = np.meshgrid(u, v, indexing='ij')
    unit = np.stack([np.cos(uu) * np.sin(vv), np.sin(uu) * np.sin(vv), np.cos(vv)], axis=-1)
    out = []
    for c in spheres:
        g = c[:3] + c[3] * unit
        q = np.stack([g[:-1, :-1], g[1:, :-1], g[1:, 1:], g[:-1, 1:]], axis=2).reshape(-1, 4, 3)
        centre = q.mean(axis=1)
        others = [o for o in spheres if o is not c]
        keep = np.ones(len(q), bool)
        for o in others:                  # a face inside another sphere is never seen
            keep &= np.linalg.norm(centre - o[:3], axis=1) > o[3]
        out.append(q[keep])
    return np.concatenate(out) if out else np.zeros((0, 4, 3))


def render_png(style, path, positions=None, title=None, views=None):
    """Render strips over the head's spheres from front, side and back into a PNG."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    strips = build_strips(style)
    quads = strip_quads(strips, positions)
    views = views or [('front', 10, 0), ('left side', 10, 90), ('back', 10, 180)]
    fig = plt.figure(figsize=(4 * len(views), 4.4), dpi=110)
    color = np.array(style.material['color'])
    head = sphere_quads(list(style.head.collision))
    hair_face = np.clip(color * 1.5 + 0.05, 0, 1)
    faces = np.concatenate([head, quads])
    face_colors = np.concatenate([np.tile([0.85, 0.72, 0.62, 1.0], (len(head), 1)),
                                  np.tile(np.append(hair_face, 1.0), (len(quads), 1))])
    edge_colors = np.concatenate([np.tile([0.6, 0.5, 0.45, 1.0], (len(head), 1)),
                                  np.tile(np.append(color * 0.5, 1.0), (len(quads), 1))])
    for i, (name, elev, azim) in enumerate(views):
        ax = fig.add_subplot(1, len(views), i + 1, projection='3d')
        ax.add_collection3d(Poly3DCollection(faces, facecolors=face_colors,
                                             edgecolors=edge_colors, linewidths=0.15))
        ax.set_xlim(-0.2, 0.2)
        ax.set_ylim(-0.2, 0.2)
        ax.set_zlim(-0.3, 0.12)
        ax.set_box_aspect((0.4, 0.4, 0.42))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title(name, fontsize=9)
    fig.suptitle(title or '%s: %d strips x %d vertices' % (style.name, strips.n_strips,
                                                           strips.n_vertices), fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return path
