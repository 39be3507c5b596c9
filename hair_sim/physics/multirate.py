"""
The multirate schedule: which strands move in each substep of a step, and by how much.

A step of h ending at t_end is split into n substeps; strand s takes counts[s] <= n of its
own, each h / counts[s] long (the count the strand model asked for: a strand at rest
beside a whipping one takes the step whole). Substep k (0-based) ends (k + 1) counts[s]
// n of strand s's own substeps: when that number grows, the strand moves by its own
length in that substep; otherwise it waits (moves by 0). A strand's own substeps thus end
spread evenly among the n, and all of them by the last. The one home of the schedule: the
driver's substep-by-substep path (HairSimulator._simulate) and the articulated model's
one-call step (articulated.chain_step) both call it.
"""

from hair_sim.kernels import njit_without_refcounts


@njit_without_refcounts
def multirate_substep(step,
                      k,
                      counts,
                      strand_h,
                      strand_t):
    """
    Write each strand's move and the end of its own substep for substep k of a step.

    step is (t_end, h, n); counts[s] (1 <= counts[s] <= n) strand s's own substeps.
    strand_h[s] gets h / counts[s] if one of strand s's own substeps ends in substep k,
    else 0 (it waits); strand_t[s] when the last of its own substeps ended by substep k
    ends: for a strand that moves, the end of the one it takes (the wind's time).
    """
    t_end, h, n = step
    for s in range(counts.shape[0]):
        ended = (k + 1) * counts[s] // n       # its own substeps ended by this one
        strand_h[s] = h / counts[s] if ended > k * counts[s] // n else 0.0
        strand_t[s] = t_end - h + ended * h / counts[s]
