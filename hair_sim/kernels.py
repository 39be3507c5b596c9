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

Every kernel is cached on disk (cache=True). numba keeps a kernel's cache in the
__pycache__ beside its source if it can write there, else in the user's cache directory
(~/.cache/numba), and a kernel it can cache in neither cannot be made at all: when hair_sim
was installed where its user cannot write (a root-owned venv, image or colcon install) and
that user has no writable home (a service account), `import hair_sim` raised "RuntimeError:
cannot cache function 'atan2_vectorizable': no locator available for file ...". Then
`use_private_cache_dir` points numba at a private directory of the system's temporary one
(NUMBA_CACHE_DIR), before the first kernel is defined (hair_sim/__init__.py imports this
module first).
"""

import os
import stat
import tempfile

from numba import njit
from numba.core import config as numba_config
from numba.misc.appdirs import AppDirs

from hair_sim.paths import PACKAGE_DIR


def _can_cache_in(path):
    """Return True if numba could keep a cache in `path`: its own test (make it, write in it)."""
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def _private_dir(path):
    """Return True if `path` is a directory of this user's alone (no symlink, mode 0700)."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return (stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid()
            and not st.st_mode & (stat.S_IRWXG | stat.S_IRWXO))


def use_private_cache_dir():
    """
    Return the cache directory hair_sim set for numba, or None where numba can cache itself.

    None when NUMBA_CACHE_DIR is set (the user's choice), or numba can write beside the
    package or into the user's cache directory. Otherwise it is <tmp>/hair_sim-numba-<uid>,
    kept across runs, if this user owns it alone (a directory someone else made there could
    plant machine code that numba would load); else a new private directory for this run.
    """
    if numba_config.CACHE_DIR:
        return None
    user_cache = AppDirs(appname='numba', appauthor=False).user_cache_dir
    if _can_cache_in(os.path.join(PACKAGE_DIR, '__pycache__')) or _can_cache_in(user_cache):
        return None
    path = os.path.join(tempfile.gettempdir(), 'hair_sim-numba-%d' % os.getuid())
    try:
        os.mkdir(path, 0o700)
    except OSError:
        pass
    if not (_private_dir(path) and _can_cache_in(path)):
        path = tempfile.mkdtemp(prefix='hair_sim-numba-')
    os.environ['NUMBA_CACHE_DIR'] = path      # (numba rereads its settings from these)
    numba_config.reload_config()
    return path


CACHE_DIR = use_private_cache_dir()

njit_without_refcounts = njit(cache=True, _nrt=False, error_model='numpy')

# The same, inlined into its callers at numba's IR level: for a small helper that takes
# bundles of arrays, where a call would copy them. Measured: culling's helper that works
# out a row's walls (culling._work_out_walls), called, made the visibility test of
# thesis_long 16 -> 19 us; inlined, 16 us as the loops written out at each call site.
inlined_without_refcounts = njit(cache=True, _nrt=False, error_model='numpy', inline='always')
