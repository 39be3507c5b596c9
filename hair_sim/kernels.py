"""
How the per-frame kernels are compiled: numba without its reference counting.

numba counts references to every array a compiled function holds, with an atomic
increment and decrement (NRT_incref / NRT_decref, a locked instruction each) whenever a
function takes an array argument or makes a view, and its pruning pass leaves the pairs
in loops and branching code in place (numba issues 2345 and 2350). Measured with perf on
the scale bench's 180-strip frame: those two runtime functions were a quarter of the
thesis model's step and more of the articulated model's, more than any kernel's own
arithmetic. A kernel compiled with `njit_without_refcounts` emits none of it: it borrows
the arrays its caller (Python, or another kernel) holds, and so it may not allocate an
array or return one (numba refuses to compile such a kernel, so this cannot go wrong
silently). Kernels that allocate keep plain `njit(cache=True)`.
"""

from numba import njit

njit_without_refcounts = njit(cache=True, _nrt=False)
