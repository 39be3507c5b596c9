"""The procedural hair texture: a valid RGBA PNG with streaks, fading edges and tip."""

import io

import numpy as np
from PIL import Image

from hair_sim import load_hairstyle, paths
from hair_sim.render.texture import texture_png, texture_rgba


def test_texture_png_is_rgba_with_alpha_fades():
    """Alpha is ~0 at both edges and the tip, high mid-strip near the root; streaks vary."""
    material = load_hairstyle(paths.shipped_style('thesis_long')).material
    tid, png = texture_png(material)
    img = np.asarray(Image.open(io.BytesIO(png)))
    assert img.shape == (material['texture']['height'], material['texture']['width'], 4)
    alpha = img[..., 3].astype(float)
    assert alpha[:, 0].max() < 20 and alpha[:, -1].max() < 20      # strip edges
    assert alpha[-1].max() < 20                                       # tip
    assert alpha[: len(alpha) // 2, img.shape[1] // 2].min() > 100   # body of the strip
    rgb = img[..., :3].astype(float)
    assert rgb[10].std(axis=0).max() > 5                              # streaks across u
    np.testing.assert_array_equal(texture_rgba(material), img)        # deterministic
    other = dict(material, texture=dict(material['texture'], seed=99))
    assert texture_png(other)[0] != tid
    assert not np.array_equal(texture_rgba(other), img)
    mean = rgb[alpha > 200].mean(axis=0) / 255
    assert np.abs(mean - np.array(material['color'])).max() < 0.15    # the material's colour


def test_a_material_seen_lately_reuses_its_texture_and_a_changed_one_does_not():
    """The cache hands back the PNG made for an equal material; any change makes a new one."""
    from hair_sim.render import texture
    material = load_hairstyle(paths.shipped_style('bob_fringe')).material
    first = texture_png(material)
    again = texture_png(dict(material))                     # equal, not the same object
    assert again[1] is first[1]
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(again[1]))),
                                  texture_rgba(material))
    changed = dict(material, texture=dict(material['texture'], tip_fade=0.5))
    assert texture_png(changed)[1] != first[1]
    for seed in range(texture.CACHE_ENTRIES + 2):            # bounded: old entries go
        texture_png(dict(material, texture=dict(material['texture'], seed=1000 + seed)))
    assert len(texture._cache) == texture.CACHE_ENTRIES
    assert texture_png(material)[1] is not first[1]          # evicted, made again
    assert texture_png(material)[1] == first[1]
