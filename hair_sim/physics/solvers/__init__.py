"""Strand models, picked by name: 'anjyo' (the thesis, eqs. 1-6) and 'articulated' (exact)."""
