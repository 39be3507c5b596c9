"""Hairstyle modeling: head models, control hairs, NURBS and the Oslo algorithm (thesis 6)."""

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import (Hairstyle, hairstyle_from_dict, load_hairstyle,
                                         Patch, save_hairstyle)
from hair_sim.modeling.head import HeadModel, load_head
from hair_sim.modeling.strips import build_strips, StripSet

__all__ = ['HairstyleError', 'Hairstyle', 'Patch', 'HeadModel', 'StripSet', 'build_strips',
           'hairstyle_from_dict', 'load_hairstyle', 'load_head', 'save_hairstyle']
