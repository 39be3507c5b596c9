"""The multirate schedule (hair_sim.physics.multirate), against what it promises."""

import numpy as np
import pytest

from hair_sim.physics.multirate import multirate_substep


@pytest.mark.parametrize('n', [1, 2, 3, 4, 7, 16])
def test_each_strand_takes_its_own_substeps_in_order_and_ends_with_the_step(n):
    """
    Every count from 1 to n: a strand moves counts[s] times, each time by h / counts[s].

    Its m-th move ends its m-th own substep, at t_end - h + m h / counts[s] (the time the
    wind is taken at), in the first substep whose end is at or after that time (a strand
    never runs ahead of the step's clock); its last move comes in the last substep, so
    its moves add up to h.
    """
    t_end, h = 3.25, 1.0 / 60.0
    counts = np.arange(1, n + 1, dtype=np.int64)
    strand_h, strand_t = np.empty(n), np.empty(n)
    moves = [[] for _ in range(n)]
    for k in range(n):
        multirate_substep((t_end, h, n), k, counts, strand_h, strand_t)
        for s in range(n):
            if strand_h[s] > 0:
                moves[s].append(k)
                assert strand_h[s] == pytest.approx(h / counts[s], rel=1e-15)
            else:
                assert strand_h[s] == 0.0
            own_end = t_end - h + len(moves[s]) * h / counts[s]
            assert strand_t[s] == pytest.approx(own_end, rel=1e-15)
            assert strand_t[s] <= t_end - h + (k + 1) * h / n + 1e-15
    for s in range(n):
        c = int(counts[s])
        assert len(moves[s]) == c
        assert moves[s][-1] == n - 1
        assert sum(h / c for _ in moves[s]) == pytest.approx(h, rel=1e-14)
        for m, k in enumerate(moves[s], start=1):
            # the first substep whose end is at or after its m-th own end
            assert k == -(-m * n // c) - 1


def test_a_strand_at_the_full_count_moves_every_substep_and_one_at_one_waits_till_the_end():
    """Counts n and 1 side by side: h / n every substep; h once, in the last."""
    n, h = 5, 0.01
    counts = np.array([n, 1], dtype=np.int64)
    strand_h, strand_t = np.empty(2), np.empty(2)
    seen = []
    for k in range(n):
        multirate_substep((1.0, h, n), k, counts, strand_h, strand_t)
        seen.append(strand_h.copy())
        assert strand_t[0] == pytest.approx(1.0 - h + (k + 1) * h / n, rel=1e-15)
        assert strand_t[1] == pytest.approx(1.0 - h if k < n - 1 else 1.0, rel=1e-15)
    seen = np.array(seen)
    np.testing.assert_allclose(seen[:, 0], h / n, rtol=1e-15)
    np.testing.assert_array_equal(seen[:, 1], [0.0] * (n - 1) + [h])
