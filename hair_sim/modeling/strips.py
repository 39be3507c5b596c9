"""
The automatic step of hairstyle modeling (thesis 6.2): control hairs -> strips.

The control points of neighbouring control hairs are connected across and refined with the
Oslo algorithm, then the refined points are connected along each hair and refined again.
Each refined column is a simulated strand (thesis 4.2, fig. 4.1B); columns 2k and 2k + 1
of a patch are the two edges of strip k.
"""

from dataclasses import dataclass

import numpy as np

from hair_sim.modeling.oslo import oslo_refine_net, refined_knots


@dataclass
class StripSet:
    """Rest geometry of all strips of a style, in the head frame."""

    rest: np.ndarray            # (n_strands, n_vertices, 3), root first
    strip_strands: np.ndarray   # (n_strips, 2) strand indices of each strip's two edges
    strip_patch: np.ndarray     # (n_strips,) patch index of each strip
    strand_u: np.ndarray        # (n_strands,) Greville abscissa across its patch, in [0, 1]
    neighbor_pairs: np.ndarray  # (n_pairs, 2) facing strands of neighbouring strips

    @property
    def n_strands(self):
        """Return the number of simulated strands (two per strip)."""
        return self.rest.shape[0]

    @property
    def n_vertices(self):
        """Return the vertices per strand, root included."""
        return self.rest.shape[1]

    @property
    def n_strips(self):
        """Return the number of strips."""
        return self.strip_strands.shape[0]


def snap_to_scalp(head, points, iterations=4):
    """Move points (n, 3) onto the boundary of the union of the head's scalp spheres."""
    p = head.nearest_on_scalp(points)
    for _ in range(iterations):
        rel = p[:, None, :] - head.scalp[None, :, :3]
        dist = np.linalg.norm(rel, axis=-1)
        depth = head.scalp[None, :, 3] - dist
        k = np.argmax(depth, axis=1)
        inside = depth[np.arange(len(p)), k] > 1e-12
        if not inside.any():
            break
        c = head.scalp[k[inside], :3]
        d = rel[inside, k[inside]] / np.maximum(dist[inside, k[inside]], 1e-12)[:, None]
        p[inside] = c + d * head.scalp[k[inside], 3][:, None]
    return p


def patch_grid(patch, n_columns, n_rows):
    """Refine one patch with Oslo to an (n_columns, n_rows, 3) grid and its Greville u."""
    tau_u = refined_knots(patch.knots_u, patch.degree_u, n_columns)
    tau_v = refined_knots(patch.knots_v, patch.degree_v, n_rows)
    net, _ = oslo_refine_net(patch.points, patch.weights, patch.knots_u, patch.knots_v,
                             patch.degree_u, patch.degree_v, tau_u, tau_v)
    p = patch.degree_u
    greville = np.array([tau_u[j + 1:j + p + 1].mean() for j in range(n_columns)])
    return net, greville


def build_strips(style):
    """Run the automatic step on every patch of `style` at its physics LOD."""
    strands, strip_strands, strip_patch, strand_u, pairs = [], [], [], [], []
    for pi, patch in enumerate(style.patches):
        net, greville = patch_grid(patch, 2 * patch.strips, style.vertices)
        base = sum(len(s) for s in strands)
        strands.append(net)
        strand_u.append(greville)
        for k in range(patch.strips):
            strip_strands.append((base + 2 * k, base + 2 * k + 1))
            strip_patch.append(pi)
            if k + 1 < patch.strips:
                pairs.append((base + 2 * k + 1, base + 2 * k + 2))
    rest = np.concatenate(strands, axis=0)
    rest[:, 0] = snap_to_scalp(style.head, rest[:, 0])
    return StripSet(rest=np.ascontiguousarray(rest),
                    strip_strands=np.array(strip_strands, dtype=np.int64).reshape(-1, 2),
                    strip_patch=np.array(strip_patch, dtype=np.int64),
                    strand_u=np.concatenate(strand_u),
                    neighbor_pairs=np.array(pairs, dtype=np.int64).reshape(-1, 2))
