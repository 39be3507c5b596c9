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

They are also compiled with numba's numpy error model: a float division by zero gives an
infinity or NaN, as in numpy, instead of a test of the divisor before every division to
raise ZeroDivisionError as Python would. Nothing relies on that exception: the kernels
test their divisors where a zero can occur, and a step whose state came out non-finite
anyway is caught by the simulator's finiteness check of the tips (which sees every NaN,
since vertices are placed root to tip). Measured at 180 strips: the thesis step 579 ->
543 us, the U-shape 661 -> 598 us, the same numbers.
"""

from numba import njit

njit_without_refcounts = njit(cache=True, _nrt=False, error_model='numpy')

# The same, inlined into its callers at numba's IR level: for a small helper that takes
# bundles of arrays, where a call would copy them. Measured: culling's helper that works
# out a row's walls (culling._work_out_walls), called, made the visibility test of
# thesis_long 16 -> 19 us; inlined, 16 us as the loops written out at each call site.
inlined_without_refcounts = njit(cache=True, _nrt=False, error_model='numpy', inline='always')
