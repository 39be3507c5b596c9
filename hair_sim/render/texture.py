"""Procedural hair texture with alpha: strand streaks, edges and tip fading out (RGBA PNG)."""

import hashlib
import io
import json

import numpy as np
from PIL import Image


def texture_rgba(material):
    """Return the (height, width, 4) uint8 texture of a material; v (rows) runs root to tip."""
    tex = material['texture']
    w, h = int(tex['width']), int(tex['height'])
    rng = np.random.default_rng(int(tex['seed']))
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    base = np.array(material['color'], dtype=np.float64)
    shade = np.full(w, 0.85)
    cover = np.zeros(w)
    for _ in range(int(tex['streaks'])):           # strands: thin bright or dark lines
        c = rng.uniform(0, 1)
        width = rng.uniform(0.6, 2.5) / w
        profile = np.exp(-0.5 * ((u - c) / width) ** 2)
        shade += rng.uniform(-0.35, 0.45) * profile
        cover = np.maximum(cover, profile)
    shade = np.clip(shade, 0.2, 1.6)
    wave = 1.0 + 0.08 * np.sin(2 * np.pi * (v[:, None] * rng.uniform(2, 5) + u[None, :] * 3))
    rgb = np.clip(base[None, None, :] * (shade[None, :, None] * wave[..., None]), 0, 1)
    e, t = float(tex['edge_fade']), float(tex['tip_fade'])
    edge = np.clip(np.minimum(u, 1 - u) / max(e, 1e-6), 0, 1)
    tip = np.clip((1 - v) / max(t, 1e-6), 0, 1)
    alpha = np.clip((0.55 + 0.45 * cover)[None, :] * edge[None, :] * tip[:, None], 0, 1)
    out = np.concatenate([rgb, alpha[..., None]], axis=-1)
    return (out * 255 + 0.5).astype(np.uint8)


def texture_png(material):
    """Return (texture_id, PNG bytes) of a material's texture; the id names its content."""
    img = texture_rgba(material)
    buf = io.BytesIO()
    Image.fromarray(img, 'RGBA').save(buf, format='PNG', optimize=False)
    data = buf.getvalue()
    tid = 'hair-' + hashlib.sha1(json.dumps(material, sort_keys=True).encode()).hexdigest()[:12]
    return tid, data
