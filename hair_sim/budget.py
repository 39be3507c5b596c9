"""
What one core of this machine kind runs at rate: the budget styles and rates are checked by.

Limits follow from cost, not from what parses. A style's cost per second is

    sim_rate * STEP_S[model] * simulated vertices  +  publish_rate * DRAW_S * drawn vertices

(seconds of one core per second), and a style or a rate change is refused before anything
is built when that exceeds CPU_SHARE of one core. The per-vertex costs are medians measured
by `hair_sim_bench budget` on this machine kind (2-core AMD EPYC VM, one core used); the
README and BENCHMARKS.md give the resulting numbers of vertices.
"""

# s per simulated vertex per solver step (forces, contacts, springs, integration)
STEP_S = {'anjyo': 3.3e-7, 'articulated': 3.3e-7}
# s per drawn vertex per published frame (tessellation + U-shape, HairMesh and state CDR,
# MarkerArray bytes at the marker rate, the meshcat encoding on its thread)
DRAW_S = 1.2e-7
# the share of one core the node plans to use; the rest is ROS, Python and jitter
CPU_SHARE = 0.7

DEFAULT_SIM_RATE = 240.0
DEFAULT_PUBLISH_RATE = 30.0


def core_share(simulated, drawn, sim_rate=DEFAULT_SIM_RATE, publish_rate=DEFAULT_PUBLISH_RATE,
               model='anjyo'):
    """Return the share of one core a style with these vertex counts needs at these rates."""
    return sim_rate * STEP_S.get(model, max(STEP_S.values())) * simulated + \
        publish_rate * DRAW_S * drawn


def max_vertices(sim_rate=DEFAULT_SIM_RATE, publish_rate=DEFAULT_PUBLISH_RATE, model='anjyo'):
    """Return (simulated vertices with nothing drawn, drawn vertices with nothing simulated)."""
    return (int(CPU_SHARE / (sim_rate * STEP_S.get(model, max(STEP_S.values())))),
            int(CPU_SHARE / (publish_rate * DRAW_S)))


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
