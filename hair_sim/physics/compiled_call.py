"""
Call a numba kernel's compiled code without typing its arguments on every call.

A numba dispatcher types every argument on every call. For a namedtuple of arrays that is
done in Python, about half a microsecond a field: the thesis model's one-call step takes
some 50 arrays in bundles, so typing cost ~35 us a step, a quarter of the step itself at
20 strips (`hair_sim_bench scale`). The argument types of a simulator's step only change
when its arrays or settings are rebuilt, so the types are worked out once per `key` (the
simulator's layout version) and the compiled overload's entry point is called directly
until the key changes. When the types have no compiled overload yet, the dispatcher is
called (it compiles) and the fast path is taken from the next call on.
"""

from numba import typeof
from numba.core.typing.typeof import Purpose


class CompiledCall:
    """A kernel called through its compiled entry point for as long as `key` holds."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self._key = None
        self._entry = None

    def __call__(self, key, *args):
        """Run the kernel on args; key changes whenever an argument's type may have."""
        if key != self._key or self._entry is None:
            self._key = key
            result = self.dispatcher(*args)          # types, compiles if needed, runs
            signature = tuple(typeof(a, Purpose.argument) for a in args)
            overload = self.dispatcher.overloads.get(signature)
            self._entry = overload.entry_point if overload is not None else None
            return result
        return self._entry(*args)
