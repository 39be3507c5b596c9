"""Rendering: Oslo tessellation at render LOD, U-shape strips, texture and culling (thesis 3)."""

from hair_sim.render.mesh import HairMesh, HairRenderer, MeshTopology

__all__ = ['HairMesh', 'HairRenderer', 'MeshTopology']
