"""Pictures of the hair with the ray caster: textured U-shape strips over a shaded head."""

import io

import numpy as np
from PIL import Image

from hair_sim.fileio import write_atomic
from hair_sim.render.mesh import HairRenderer
from hair_sim.render.raster import Camera
from hair_sim.render.texture import texture_rgba

SKIN = np.array([0.87, 0.72, 0.62])
BACKGROUND = np.array([1.0, 1.0, 1.0])


def shade(mesh, spheres, camera, texture=None, alpha_cut=60):
    """Return an (h, w, 3) float image of the mesh (textured if given) and the spheres."""
    hd, tri, bary = camera.render_mesh(mesh.vertices, mesh.indices, mesh.uvs, texture,
                                       alpha_cut=alpha_cut)
    sd, sid = camera.render_spheres(spheres)
    h, w = hd.shape
    img = np.tile(BACKGROUND, (h, w, 1))
    light = -camera.rot[2] + 0.6 * camera.rot[1] * -1 + 0.3 * camera.rot[0]
    light /= np.linalg.norm(light)
    ys, xs = np.mgrid[0:h, 0:w]
    dirs = np.stack([(xs + 0.5 - 0.5 * w) / camera.focal, (ys + 0.5 - 0.5 * h) / camera.focal,
                     np.ones_like(xs, dtype=float)], axis=-1) @ camera.rot
    head = (sid >= 0) & (sd <= hd)
    if head.any():
        hit = camera.eye + dirs[head] * sd[head][:, None]
        n = hit - spheres[sid[head], :3]
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        lam = np.clip(n @ light, 0, 1)
        img[head] = SKIN * (0.35 + 0.65 * lam[:, None])
    hair = (tri >= 0) & (hd < sd)
    if hair.any():
        t = tri[hair]
        v = mesh.vertices.astype(np.float64)[mesh.indices[t]]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-18)
        lam = np.abs(n @ light)
        b = bary[hair]
        if texture is not None:
            uv = mesh.uvs[mesh.indices[t]].astype(np.float64)
            w = np.stack([b[:, 0], b[:, 1], 1 - b[:, 0] - b[:, 1]], axis=1)
            u = (w * uv[:, :, 0]).sum(axis=1)
            vv = (w * uv[:, :, 1]).sum(axis=1)
            tx = np.clip((u * texture.shape[1]).astype(int), 0, texture.shape[1] - 1)
            ty = np.clip((vv * texture.shape[0]).astype(int), 0, texture.shape[0] - 1)
            col = texture[ty, tx, :3] / 255.0
        else:
            col = np.tile([0.45, 0.3, 0.18], (len(t), 1))
        img[hair] = np.clip(col * (0.45 + 0.75 * lam[:, None]), 0, 1)
    return img


def views_png(sim, path, size=300):
    """Write plain strips (top row) and textured U-shape strips (bottom) from 3 views."""
    R, p = sim.head_pose
    renderer = HairRenderer.for_simulator(sim)
    plain = renderer.mesh(sim.pos, R, p, walls=False)
    full = renderer.mesh(sim.pos, R, p)
    texture = texture_rgba(sim.style.material)
    spheres = sim.head.collision.copy()
    spheres[:, :3] = spheres[:, :3] @ R.T + p
    target = p + R @ np.array([0.0, 0.0, -0.04])
    eyes = [R @ np.array(e) + p for e in ([0.75, 0.0, 0.12], [0.0, 0.75, 0.12],
                                          [-0.75, 0.0, 0.12])]
    rows = []
    for mesh, tex in ((plain, None), (full, texture)):
        rows.append(np.concatenate([shade(mesh, spheres, Camera(e, target, 32, size, size),
                                          tex) for e in eyes], axis=1))
    img = (np.concatenate(rows, axis=0) * 255 + 0.5).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format='PNG')
    return write_atomic(path, buf.getvalue())
