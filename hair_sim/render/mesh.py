"""HairMesh, the one input of every sink, and HairRenderer, which builds it each frame."""

from dataclasses import dataclass

from numba import njit
import numpy as np

from hair_sim.kernels import njit_without_refcounts
from hair_sim.render import culling, ushape
from hair_sim.render.tessellate import make_lod
from hair_sim.render.texture import texture_png

DELTA = 5e-4            # m: bisection threshold of thesis 3.2
MAX_DISTANCE = 0.04     # m: a projection farther than this from its vertex is "too far"
FIX_LENGTH = 0.006      # m: C, the length of a fixed-up projection AA' (fig. 3.4 B, D)
# culling forgets the strips it draws unproven when the eye, seen from the head, moves more
# than this share of its distance between two calls (a new view, not a frame's motion)
VIEW_JUMP = 0.05


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


@njit_without_refcounts
def _world_projection(head, R, p, scratch):
    """
    Return the Projection (world) of a head under pose (R, p), written into scratch.

    head is (scalp spheres, occluding spheres, projection centre (head frame), rs, delta,
    max_dist, fix_len); scratch (scalp, occluding spheres, centre, world; the last eye).
    """
    scalp_head, _, centre_head, rs, delta, max_dist, fix_len = head
    scalp, _, centre, _ = scratch
    _spheres_to_world(scalp_head, R, p, scalp)
    for a in range(3):
        centre[a] = R[a, 0] * centre_head[0] + R[a, 1] * centre_head[1] + \
            R[a, 2] * centre_head[2] + p[a]
    return ushape.Projection(scalp, centre, rs, delta, max_dist, fix_len)


@njit_without_refcounts
def _spheres_to_world(spheres, R, p, out):
    """Write spheres (n, 4) (head frame) moved by the pose (R, p) into out."""
    for k in range(spheres.shape[0]):
        for a in range(3):
            out[k, a] = R[a, 0] * spheres[k, 0] + R[a, 1] * spheres[k, 1] + \
                R[a, 2] * spheres[k, 2] + p[a]
        out[k, 3] = spheres[k, 3]


@njit_without_refcounts
def seen_strips(pos, strips, head, pose, scratch, visible):
    """
    Write the strips that may be seen from the eye into visible[:count]; return count.

    The arguments are mesh_vertices' (pose (R, p, eye)): culling.visible_strips with the
    head's spheres moved into the world first (_seen_strips).
    """
    R, p = pose[0], pose[1]
    return _seen_strips(pos, strips, _world_projection(head, R, p, scratch[0]), head[1],
                        pose, scratch, visible)


@njit_without_refcounts
def _seen_strips(pos, strips, projection, occ_head, pose, scratch, visible):
    """
    seen_strips, given the world Projection; occ_head the occluding spheres (head frame).

    What culling remembers from call to call (proof_rest, the strips drawn unproven)
    belongs to a view: when the eye, seen from the head, moved more than VIEW_JUMP of its
    distance since the last call, it is forgotten.
    """
    R, p, eye = pose
    world, cull_scratch, _ = scratch
    last_eye = world[3]                          # the eye in the head frame, last call
    ex, ey, ez = eye[0] - p[0], eye[1] - p[1], eye[2] - p[2]
    hx = R[0, 0] * ex + R[1, 0] * ey + R[2, 0] * ez
    hy = R[0, 1] * ex + R[1, 1] * ey + R[2, 1] * ez
    hz = R[0, 2] * ex + R[1, 2] * ey + R[2, 2] * ez
    dx, dy, dz = hx - last_eye[0], hy - last_eye[1], hz - last_eye[2]
    if dx * dx + dy * dy + dz * dz > VIEW_JUMP * VIEW_JUMP * (hx * hx + hy * hy + hz * hz):
        proof_rest = strips[2]
        for s in range(proof_rest.shape[0]):
            proof_rest[s] = 0
    last_eye[0], last_eye[1], last_eye[2] = hx, hy, hz
    _spheres_to_world(occ_head, R, p, world[1])
    return culling.visible_strips(pos, strips, projection, (eye, world[1]), cull_scratch,
                                  visible)


@njit_without_refcounts
def mesh_vertices(pos, strips, lod, head, pose, scratch, out):
    """
    Write the U-shape vertices of the strips drawn (all, or those seen); return how many.

    One call from Python a frame: a call's bundled arguments cost about 1 us to pass,
    as much as a strip's U-shape. strips is (strip_strands, sigma, proof_rest, proofs)
    (culling.visible_strips), lod (along, across), head (scalp spheres, occluding spheres
    shrunk a shade, projection centre, all head frame, then rs, delta, max_dist, fix_len),
    pose (R, p, eye, cull): with cull only
    the strips that may be seen from the eye (world) are drawn (culling.visible_strips).
    scratch is (world (scalp, occluding spheres, centre; the eye in the head frame last
    call), culling's, ushape's); out
    (visible strips, grids, U-shape vertices, flags), the drawn strips first.
    """
    R, p, eye, cull = pose
    along, across = lod
    strip_strands, sigma = strips[0], strips[1]
    world, cull_scratch, wall_scratch = scratch
    visible, grid, vertices, flags = out
    projection = _world_projection(head, R, p, world)
    if cull:
        count = _seen_strips(pos, strips, projection, head[1], (R, p, eye), scratch, visible)
    else:
        count = strip_strands.shape[0]
        for s in range(count):
            visible[s] = s
    drawn = visible[:count]
    ushape.tessellate_strips(pos, strip_strands, drawn, along, across, grid)
    ushape.ushape(grid[:count], sigma, drawn, projection, vertices[:count], flags[:count],
                  wall_scratch)
    return count


def _f64(a):
    """Return a as a C-contiguous float64 array (no copy when it is one)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _eye(viewpoint):
    """
    Return a viewpoint as 3 float64s; raise ValueError unless it is 3 finite numbers.

    (The kernels read its three components unchecked: a 2-vector was read past its end,
    and a NaN one drew every strip, both without a word.)
    """
    try:
        eye = _f64(viewpoint)
    except (TypeError, ValueError):
        eye = None
    if eye is None or eye.shape != (3,) or not np.all(np.isfinite(eye)):
        raise ValueError('viewpoint must be 3 finite numbers (world frame, m), not %r'
                         % (viewpoint,))
    return eye


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
        self._vis = np.zeros(self.n_strips, dtype=np.int64)   # drawn strips, culling writes
        # what culling keeps from call to call: the strips it draws unproven, and the
        # certificates of those it proved hidden
        self._proof_rest = np.zeros(self.n_strips, dtype=np.int64)
        self._proofs = np.full((self.n_strips, rest.shape[1] - 1), -1, dtype=np.int64)
        self._culled = None             # (strips as bytes, their triangles), last culled mesh
        # the head's spheres in its frame, and their world copies the kernels write
        occ = np.array(head.collision, dtype=np.float64)
        occ[:, 3] -= 1e-4                       # a shade smaller: culling stays conservative
        scalp = np.ascontiguousarray(head.scalp, dtype=np.float64)
        rs = 0.0 if point_centre else float(head.projection_sphere[3])
        self._head = (scalp, occ,
                      np.ascontiguousarray(head.projection_sphere[:3], dtype=np.float64),
                      rs, float(delta), float(max_distance), float(fix_length))
        self._scratch = ((np.zeros_like(scalp), np.zeros_like(occ), np.zeros(3),
                          np.zeros(3)),
                         culling.culling_scratch(rest.shape, len(occ), len(scalp)),
                         ushape.wall_scratch(len(scalp)))
        self._no_eye = np.zeros(3)
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
        if viewpoint is not None:
            viewpoint = _eye(viewpoint)
        key = (sim.state_version, None if viewpoint is None else tuple(viewpoint))
        if self._last_key != key:
            R, p = sim.head_pose
            self._last = self.mesh(sim.pos, R, p, viewpoint)
            self._last_key = key
        return self._last

    def projection(self, R, p):
        """Return the U-shape's Projection (world) under head pose (R, p) (a copy)."""
        scalp_head, _, centre_head, rs, delta, max_dist, fix_len = self._head
        R, p = _f64(R), _f64(p)
        scalp = np.zeros_like(scalp_head)
        _spheres_to_world(scalp_head, R, p, scalp)
        return ushape.Projection(scalp=scalp, centre=R @ centre_head + p, rs=rs, delta=delta,
                                 max_dist=max_dist, fix_len=fix_len)

    def visible(self, pos, R, p, viewpoint):
        """Return the indices of the strips that may be seen from `viewpoint` (world)."""
        count = seen_strips(
            pos,
            (self.strip_strands, self.sigma, self._proof_rest, self._proofs),
            self._head,
            (_f64(R), _f64(p), _eye(viewpoint)),
            self._scratch,
            self._vis,
        )
        return self._vis[:count].copy()

    def mesh(self, pos, R, p, viewpoint=None, frame_id='world', walls=True):
        """
        Build the HairMesh of strand positions `pos` (world) under head pose (R, p).

        walls=False leaves out the two projected meshes: plain strips (thesis fig. 3.8a).
        """
        k = mesh_vertices(
            pos,
            (self.strip_strands, self.sigma, self._proof_rest, self._proofs),
            (self.lod.along, self.lod.across),
            self._head,
            (_f64(R), _f64(p), self._no_eye if viewpoint is None else _eye(viewpoint),
             viewpoint is not None),
            self._scratch,
            (self._vis, self._grid, self._out, self._flags),
        )
        sel = self._all if viewpoint is None else self._vis[:k]
        out = self._out[:k]
        flags = self._flags[:k]
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
