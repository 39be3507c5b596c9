"""
Render LOD: refine each strip's simulated net with the Oslo algorithm (thesis 2, 6.2).

The simulated strands of a strip (two edges, V vertices each) are the control points of a
strip surface: degree 1 across, clamped uniform degree 3 (or less) along. The Oslo matrices
that refine it to `render_columns` x `render_rows` depend only on the LOD, so they are
computed once here and a frame's tessellation is a small matrix product per strip.
"""

from dataclasses import dataclass

import numpy as np

from hair_sim.modeling.nurbs import clamped_uniform_knots
from hair_sim.modeling.oslo import oslo_matrix, refined_knots


@dataclass
class RenderLOD:
    """Oslo matrices, UVs and triangle templates of one render level of detail."""

    n_vertices: int         # simulated vertices per strand
    rows: int               # drawn rows per strip (root to tip)
    columns: int            # drawn columns per strip (across, >= 2)
    along: np.ndarray       # (rows, n_vertices) Oslo matrix along a strand
    across: np.ndarray      # (columns, 2) Oslo matrix across a strip (degree 1)
    uvs: np.ndarray         # (verts_per_strip, 2) float32, the same for every strip
    triangles: np.ndarray   # (tris_per_strip, 3) uint32, indices local to a strip

    @property
    def verts_per_strip(self):
        """Return the vertices of one U-shaped strip: its grid plus two walls of 2 x rows."""
        return (self.columns + 4) * self.rows

    @property
    def tris_per_strip(self):
        """Return the triangles of one U-shaped strip: 2 (columns + 1) (rows - 1)."""
        return 2 * (self.columns + 1) * (self.rows - 1)


def make_lod(n_vertices, rows, columns):
    """Build the Oslo matrices and the per-strip UV / triangle templates of a render LOD."""
    if rows < n_vertices or columns < 2:
        raise ValueError('render LOD needs rows >= simulated vertices and columns >= 2')
    degree = min(3, n_vertices - 1)
    t = clamped_uniform_knots(n_vertices, degree)
    along = oslo_matrix(t, refined_knots(t, degree, rows), degree)
    t1 = clamped_uniform_knots(2, 1)
    across = oslo_matrix(t1, refined_knots(t1, 1, columns), 1)
    R, C = rows, columns
    v = np.linspace(0.0, 1.0, R)
    # layout: grid (C x R, column-major), left wall (edge, projection) x R, right wall
    grid_uv = np.stack(np.meshgrid(np.linspace(0, 1, C), v, indexing='ij'), -1).reshape(-1, 2)
    wall_uv = np.stack(np.meshgrid([0.0, 1.0], v, indexing='ij'), -1).reshape(-1, 2)
    uvs = np.concatenate([grid_uv, wall_uv, wall_uv]).astype(np.float32)
    tris = []

    def quad(a0, a1, b0, b1):         # a0-a1 one side (rows r, r+1), b0-b1 the other
        tris.append((a0, b0, b1))
        tris.append((a0, b1, a1))

    for c in range(C - 1):            # strip: outer face counter-clockwise for sigma = +1
        for r in range(R - 1):
            quad(c * R + r, c * R + r + 1, (c + 1) * R + r, (c + 1) * R + r + 1)
    left, right = C * R, C * R + 2 * R
    for r in range(R - 1):            # left wall faces away from the strip (-u side)
        quad(left + R + r, left + R + r + 1, left + r, left + r + 1)
    for r in range(R - 1):            # right wall faces +u
        quad(right + r, right + r + 1, right + R + r, right + R + r + 1)
    return RenderLOD(n_vertices=n_vertices, rows=R, columns=C, along=along, across=across,
                     uvs=uvs, triangles=np.array(tris, dtype=np.uint32))
