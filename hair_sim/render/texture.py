"""Procedural hair texture with alpha: strand streaks, edges and tip fading out (RGBA PNG)."""

from collections import OrderedDict
import hashlib
import io
import json
import threading

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


# Textures made lately, by material: building and encoding one is most of a renderer's
# set-up (~10 of 15 ms), and a node re-loading styles makes the same ones again
CACHE_ENTRIES = 8
CACHE_MAX_PNG_BYTES = 1 << 20
_cache = OrderedDict()
_cache_lock = threading.Lock()


def texture_png(material):
    """Return (texture_id, PNG bytes) of a material's texture; the id names its content."""
    key = json.dumps(material, sort_keys=True)
    with _cache_lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            return hit
    img = texture_rgba(material)
    buf = io.BytesIO()
    Image.fromarray(img, 'RGBA').save(buf, format='PNG', optimize=False)
    data = buf.getvalue()
    made = 'hair-' + hashlib.sha1(key.encode()).hexdigest()[:12], data
    if len(data) <= CACHE_MAX_PNG_BYTES:
        with _cache_lock:
            _cache[key] = made
            while len(_cache) > CACHE_ENTRIES:
                _cache.popitem(last=False)
    return made
