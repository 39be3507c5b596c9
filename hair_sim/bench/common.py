"""Shared pieces of the benchmark commands: progress, timing, JSON and plots."""

import json
import os
import sys
import time

import numpy as np

from hair_sim.fileio import save_figure  # noqa: F401 (the benches' one place to save)

DT_FULL = [1 / 4000, 1 / 2000, 1 / 1000, 1 / 480, 1 / 240, 1 / 120, 1 / 60, 1 / 30]
DT_QUICK = [1 / 1000, 1 / 240, 1 / 60]


def progress(iterable, desc, total=None):
    """Wrap an iterable in a tqdm progress bar on stderr."""
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, file=sys.stderr, leave=False,
                disable=not sys.stderr.isatty() and os.environ.get('HAIR_SIM_PROGRESS') != '1')


def cpu_time(fn, *args, **kwargs):
    """Return (result, CPU seconds of this process) of fn(*args)."""
    t0 = time.process_time()
    out = fn(*args, **kwargs)
    return out, time.process_time() - t0


def clean(value):
    """Make value JSON-safe (NaN and inf become None; numpy scalars become Python)."""
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if np.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def emit(records, as_json, title):
    """Print records as JSON (or a short table) on stdout."""
    records = clean(records)
    if as_json:
        print(json.dumps(records, indent=1))
        return
    print(title)
    for r in records:
        print('  ' + ', '.join('%s=%s' % (k, ('%.4g' % v) if isinstance(v, float) else v)
                               for k, v in r.items()))
