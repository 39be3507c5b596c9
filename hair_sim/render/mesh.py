"""HairMesh, the one input of every sink, and HairRenderer, which builds it each frame."""

from dataclasses import dataclass

from numba import njit
import numpy as np

from hair_sim.render import culling, ushape
from hair_sim.render.tessellate import make_lod
from hair_sim.render.texture import texture_png

DELTA = 5e-4            # m: bisection threshold of thesis 3.2
MAX_DISTANCE = 0.04     # m: a projection farther than this from its vertex is "too far"
FIX_LENGTH = 0.006      # m: C, the length of a fixed-up projection AA' (fig. 3.4 B, D)


@dataclass
class HairMesh:
    """
    A triangle mesh of the drawn hair.

    vertices (N, 3) float32, uvs (N, 2) float32 (u across a strip, v root 0 -> tip 1),
    indices (M, 3) uint32 counter-clockwise seen from outside, strip_offsets (S + 1,)
    triangle index where each drawn strip starts, strip_ids (S,) which strip of the style
    each is, texture_png (RGBA PNG bytes) and texture_id naming it, frame_id of the vertices.
    Each drawn strip has (columns + 4) * rows vertices and 2 (columns + 1)(rows - 1)
    triangles: its grid and its two walls (thesis 3.1).
    """

    vertices: np.ndarray
    uvs: np.ndarray
    indices: np.ndarray
    strip_offsets: np.ndarray
    strip_ids: np.ndarray
    texture_png: bytes
    texture_id: str
    frame_id: str = 'world'
    verts_per_strip: int = 0
    tris_per_strip: int = 0
    flags: np.ndarray = None        # (S, 2, rows): 0 projected, 1 too far, 2 reverse volume

    @property
    def n_strips(self):
        """Return the number of drawn strips."""
        return len(self.strip_ids)


@dataclass(frozen=True)
class MeshTopology:
    """
    What the mesh of every strip of a style has apart from its vertices (one per renderer).

    uvs (n_strips * verts_per_strip, 2) float32, indices (n_strips * tris_per_strip, 3)
    uint32 numbering every strip's vertices s * verts_per_strip onwards, strip_offsets
    (n_strips + 1,) uint32, and the texture. A HairMesh of k drawn strips (strip_ids) is
    laid out by it: its vertices are those strips' blocks, in order.
    """

    n_strips: int
    verts_per_strip: int
    tris_per_strip: int
    uvs: np.ndarray
    indices: np.ndarray
    strip_offsets: np.ndarray
    texture_id: str
    texture_png: bytes


@njit(cache=True)
def culled_triangles(local, strips, verts_per_strip):
    """
    Return the triangles (k * tris_per_strip, 3) of a mesh of the listed strips only.

    local (n_strips, tris_per_strip, 3) holds each strip's triangles numbered from 0; the
    i-th listed strip's vertices start at i * verts_per_strip.
    """
    nt = local.shape[1]
    out = np.empty((strips.shape[0] * nt, 3), dtype=np.uint32)
    for i in range(strips.shape[0]):
        s = strips[i]
        base = i * verts_per_strip
        for t in range(nt):
            for c in range(3):
                out[i * nt + t, c] = local[s, t, c] + base
    return out


@njit(cache=True)
def tessellate_visible_strips(pos, strips, lod, view, scratch, visible, grid):
    """
    Cull and tessellate in one call; return how many strips may be seen.

    The strips that may be seen from the eye go into visible[:count]
    (culling.visible_strips), their grids into grid. strips is (strip_strands, sigma), lod
    (along, across), view (projection, eye, occluding spheres). One call from Python
    instead of two: a call's arguments cost about 2 us to pass, as much as a strip's
    U-shape.
    """
    strip_strands, sigma = strips
    projection, eye, occ = view
    count = culling.visible_strips(pos, strip_strands, sigma, projection, eye, occ, scratch,
                                   visible)
    ushape.tessellate_strips(pos, strip_strands, visible[:count], lod[0], lod[1], grid)
    return count


class HairRenderer:
    """Tessellate (Oslo), warp into U-shapes (3.2), texture and cull the strips of a style."""

    def __init__(self, style, strips, rest, head, point_centre=False, delta=DELTA,
                 max_distance=MAX_DISTANCE, fix_length=FIX_LENGTH):
        self.lod = make_lod(strips.n_vertices, style.render_rows, style.render_columns)
        self.strip_strands = np.ascontiguousarray(strips.strip_strands)
        self.n_strips = strips.n_strips
        self.head = head
        self.point_centre = point_centre
        self.delta, self.max_distance, self.fix_length = delta, max_distance, fix_length
        self.texture_id, self.texture = texture_png(style.material)
        # sigma: +1 where the strip's AB x AC normal faces the scalp at rest (thesis 3.1)
        mid = rest.shape[1] // 2
        m0, m1 = max(mid - 1, 0), min(mid + 1, rest.shape[1] - 1)
        left, right = rest[self.strip_strands[:, 0]], rest[self.strip_strands[:, 1]]
        n = np.array([ushape.strip_normal(a[mid], b[mid], a[m0], b[m0], a[m1], b[m1])
                      for a, b in zip(left, right)]).reshape(-1, 3)
        towards = head.nearest_on_scalp(left[:, mid]) - left[:, mid]
        self.sigma = np.where((n * towards).sum(axis=1) >= 0, 1.0, -1.0)
        tri = self.lod.triangles.astype(np.int64)
        self._tri_out = tri                               # outward when sigma = -1
        self._tri_flip = tri[:, [0, 2, 1]]
        self._all = np.arange(self.n_strips)
        # what a mesh of k strips takes apart from its vertices, built once per style: each
        # strip's triangles (turned to face out) numbered from 0, UVs and offsets of k strips
        nv, nt = self.lod.verts_per_strip, self.lod.tris_per_strip
        self._local = np.where((self.sigma > 0)[:, None, None], self._tri_flip[None],
                               self._tri_out[None]).astype(np.uint32)
        self._base = (np.arange(self.n_strips) * nv).astype(np.uint32)[:, None, None]
        self._uvs_all = np.tile(self.lod.uvs, (self.n_strips, 1))
        self._offsets_all = (np.arange(self.n_strips + 1) * nt).astype(np.uint32)
        self._topology = None
        self._grid = np.zeros((self.n_strips, self.lod.columns, self.lod.rows, 3))
        self._out = np.zeros((self.n_strips, self.lod.verts_per_strip, 3))
        self._flags = np.zeros((self.n_strips, 2, self.lod.rows), dtype=np.int64)
        self._vis = np.zeros(self.n_strips, dtype=np.int64)   # visible strips, culling writes
        self._culled = None             # (strips as bytes, their triangles), last culled mesh
        self._wall_scratch = (np.zeros_like(rest), np.zeros_like(rest))   # reach, bottoms
        self._collision = head.collision      # (head frame; stacked once, not every frame)
        self._walls = ushape.wall_scratch(len(head.scalp))    # ushape's scratch
        self._last_key = None
        self._last = None

    def topology(self):
        """Return the MeshTopology of every strip (built once; it never changes)."""
        if self._topology is None:
            nv, nt = self.lod.verts_per_strip, self.lod.tris_per_strip
            self._topology = MeshTopology(
                n_strips=self.n_strips, verts_per_strip=nv, tris_per_strip=nt,
                uvs=self._uvs_all, indices=(self._local + self._base).reshape(-1, 3),
                strip_offsets=self._offsets_all, texture_id=self.texture_id,
                texture_png=self.texture)
        return self._topology

    @classmethod
    def for_simulator(cls, sim, point_centre=False):
        """Return the renderer of a simulator's style and strands."""
        return cls(sim.style, sim.strips, sim.rest, sim.head, point_centre=point_centre)

    def mesh_of(self, sim, viewpoint=None):
        """
        Return the HairMesh of a simulator's current state (world frame, thesis 3).

        The mesh is a function of the state, so while the hair sleeps (the state does not
        change) the last one is handed out again: sleeping hair costs no rendering either.
        """
        key = (sim.state_version, None if viewpoint is None else tuple(
            float(v) for v in viewpoint))
        if self._last_key != key:
            R, p = sim.head_pose
            self._last = self.mesh(sim.pos, R, p, viewpoint)
            self._last_key = key
        return self._last

    def _world(self, R, p):
        scalp = self.head.scalp.copy()
        scalp[:, :3] = scalp[:, :3] @ R.T + p
        occ = self._collision.copy()
        occ[:, :3] = occ[:, :3] @ R.T + p
        occ[:, 3] -= 1e-4                      # a shade smaller: culling stays conservative
        centre = self.head.projection_sphere[:3] @ R.T + p
        rs = 0.0 if self.point_centre else float(self.head.projection_sphere[3])
        projection = ushape.Projection(scalp=np.ascontiguousarray(scalp), centre=centre, rs=rs,
                                       delta=self.delta, max_dist=self.max_distance,
                                       fix_len=self.fix_length)
        return projection, np.ascontiguousarray(occ)

    def visible(self, pos, R, p, viewpoint, world=None):
        """Return the indices of the strips that may be seen from `viewpoint` (world)."""
        projection, occ = self._world(R, p) if world is None else world
        count = culling.visible_strips(
            pos,
            self.strip_strands,
            self.sigma,
            projection,
            np.asarray(viewpoint, dtype=np.float64),
            occ,
            self._wall_scratch,
            self._vis,
        )
        return self._vis[:count].copy()

    def mesh(self, pos, R, p, viewpoint=None, frame_id='world', walls=True):
        """
        Build the HairMesh of strand positions `pos` (world) under head pose (R, p).

        walls=False leaves out the two projected meshes: plain strips (thesis fig. 3.8a).
        """
        world = self._world(R, p)
        projection = world[0]
        if viewpoint is None:
            sel = self._all
            k = len(sel)
            ushape.tessellate_strips(pos, self.strip_strands, sel, self.lod.along,
                                     self.lod.across, self._grid)
        else:
            k = tessellate_visible_strips(
                pos,
                (self.strip_strands, self.sigma),
                (self.lod.along, self.lod.across),
                (projection, np.asarray(viewpoint, dtype=np.float64), world[1]),
                self._wall_scratch,
                self._vis,
                self._grid,
            )
            sel = self._vis[:k]
        grid = self._grid[:k]
        out = self._out[:k]
        flags = self._flags[:k]
        ushape.ushape(
            grid,
            self.sigma,
            sel,
            projection,
            out,
            flags,
            self._walls,
        )
        nv, nt = self.lod.verts_per_strip, self.lod.tris_per_strip
        if viewpoint is None:                  # every strip: the topology's arrays
            topology = self.topology()
            indices, uvs, offsets = topology.indices, topology.uvs, topology.strip_offsets
        else:
            # the same strips as last frame (the usual case): the same triangles
            # (compared as bytes: a tenth of np.array_equal's cost on a few dozen strips)
            if self._culled is None or self._culled[0] != sel.tobytes():
                self._culled = (sel.tobytes(), culled_triangles(self._local, sel, nv))
            indices = self._culled[1]
            uvs = self._uvs_all[:k * nv]
            offsets = self._offsets_all[:k + 1]
        self.last_f64 = out                 # float64 U-shape vertices of this frame (k, nv, 3)
        if not walls:
            keep = (np.arange(nt) < 2 * (self.lod.columns - 1) * (self.lod.rows - 1))
            indices = indices.reshape(k, nt, 3)[:, keep].reshape(-1, 3)
            offsets = (np.arange(k + 1) * int(keep.sum())).astype(np.uint32)
            nt = int(keep.sum())
        return HairMesh(vertices=out.reshape(-1, 3).astype(np.float32), uvs=uvs,
                        indices=indices, strip_offsets=offsets,
                        strip_ids=sel.astype(np.uint32), texture_png=self.texture,
                        texture_id=self.texture_id, frame_id=frame_id,
                        verts_per_strip=nv, tris_per_strip=nt, flags=flags.copy())
