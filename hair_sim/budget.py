"""
What one core of this machine kind runs at rate: the budget styles and rates are checked by.

Limits follow from cost, not from what parses. A style's cost per second is

    sim_rate * (STEP_FIXED_S + STEP_S[model] * simulated vertices)
    + publish_rate * (FRAME_FIXED_S + DRAW_S * drawn vertices)

(seconds of one core per second), and a style or a rate change is refused before anything
is built when that exceeds CPU_SHARE of one core. The costs are least-squares fits measured
by `hair_sim_bench budget` on this machine kind (2-core AMD EPYC VM, one core used); a
published frame includes the U-shape mesh, HairMesh and HairState bytes, the MarkerArray at
the shipped marker_rate / publish_rate and the meshcat encoding at meshcat.rate /
publish_rate. The README and BENCHMARKS.md give the resulting numbers of vertices.
"""

# s per solver step: fixed (Python, head motion) and per simulated vertex
STEP_FIXED_S = {'anjyo': 1.4e-4, 'articulated': 1.8e-4}
STEP_S = {'anjyo': 3.8e-7, 'articulated': 1.1e-6}
# s per published frame: fixed and per drawn vertex
FRAME_FIXED_S = 2.0e-4
DRAW_S = 9.0e-8
# the share of one core the node plans to use; the rest is ROS, Python and jitter
CPU_SHARE = 0.7

DEFAULT_SIM_RATE = 240.0
DEFAULT_PUBLISH_RATE = 30.0


def _step(model):
    return (STEP_FIXED_S.get(model, max(STEP_FIXED_S.values())),
            STEP_S.get(model, max(STEP_S.values())))


def core_share(simulated, drawn, sim_rate=DEFAULT_SIM_RATE, publish_rate=DEFAULT_PUBLISH_RATE,
               model='anjyo'):
    """Return the share of one core a style with these vertex counts needs at these rates."""
    fixed, per = _step(model)
    return sim_rate * (fixed + per * simulated) + \
        publish_rate * (FRAME_FIXED_S + DRAW_S * drawn)


def max_vertices(sim_rate=DEFAULT_SIM_RATE, publish_rate=DEFAULT_PUBLISH_RATE, model='anjyo'):
    """Return (simulated vertices with nothing drawn, drawn vertices with nothing simulated)."""
    fixed, per = _step(model)
    free = CPU_SHARE - sim_rate * fixed - publish_rate * FRAME_FIXED_S
    return max(0, int(free / (sim_rate * per))), max(0, int(free / (publish_rate * DRAW_S)))


def budget_problem(simulated, drawn, sim_rate=DEFAULT_SIM_RATE,
                   publish_rate=DEFAULT_PUBLISH_RATE, model='anjyo'):
    """Return why this load would not run at rate on one core, or None if it fits."""
    share = core_share(simulated, drawn, sim_rate, publish_rate, model)
    if share <= CPU_SHARE:
        return None
    n_sim, n_drawn = max_vertices(sim_rate, publish_rate, model)
    return ('over the frame budget: %d simulated vertices at %g Hz and %d drawn vertices at '
            '%g Hz need %.0f%% of a core (the budget is %.0f%%); this machine runs at most '
            '%d simulated or %d drawn vertices at these rates'
            % (simulated, sim_rate, drawn, publish_rate, 100 * share, 100 * CPU_SHARE,
               n_sim, n_drawn))
