"""
hair_sim_bench: benchmarks that print JSON and write PNG plots.

    hair_sim_bench accuracy [--json] [--quick] [--plots DIR]   work-precision
    hair_sim_bench scale    [--json] [--quick] [--plots DIR]   cost against strips
    hair_sim_bench skip     [--json] [--quick]                 features on and off
    hair_sim_bench stress   [--json] [--quick] [--plots DIR] [--model M] [--shape-stiffness S]
                                stability under abuse (M: anjyo, the default, or articulated;
                                S: the articulated model's shape springs, default 0)
    hair_sim_bench settle   [--json] [--quick] [--model M] [--shape-stiffness S]
                                every shipped style at every step: asleep within 8 s of
                                violent motion in wind?
    hair_sim_bench node     [--json] [--quick]                 the node from outside:
                                rates, latency, CPU, avatars per machine, load gaps
    hair_sim_bench budget   [--json] [--quick]                 per-vertex costs behind
                                the frame budget (hair_sim/budget.py)
    hair_sim_bench hanging  [--json] [--quick] [--plots DIR]   the hanging-hair scene:
                                both models against MuJoCo (make setup installs it)
    hair_sim_bench materials [--json] [--quick]                the same scene with other
                                strands (stiffer, limper, shorter, longer, little air
                                damping) and MuJoCo's contacts stiffer
    hair_sim_bench turn     [--json] [--quick] [--plots DIR]   the same scene on a head
                                that turns, nods and slides: the exact chain against
                                MuJoCo with the head as a prescribed base (make setup
                                installs it)
    hair_sim_bench style    [--json] [--quick]                 every shipped style in the
                                demo's gusts: how far from its look, and back after?
    hair_sim_bench fall     [--json] [--quick] [--plots DIR]   the strands the stress
                                gale leaves moving (articulated), run on in MuJoCo from the
                                same state (make setup installs it)
    hair_sim_bench viewer   [--json] [--quick]                 a browser page that stops
                                reading or reads slowly: the meshcat server's memory and
                                how old the page's hair gets (hair_sim's server, meshcat's)
    hair_sim_bench jitter   [--json] [--quick]                 a noisy head tracker:
                                how far the tips stray, with motion_smoothing and the
                                deadbands, and what they cost on a real turn
"""

import argparse
import json
import os
import sys

from hair_sim.bench.common import clean, emit
from hair_sim.physics.params import PhysicsParams


# the commands that write --plots
PLOTTING = ('accuracy', 'scale', 'stress', 'hanging', 'fall', 'turn')


def plots_folder_problem(path):
    """
    Return why the plots cannot be written into `path` (made if missing), or None.

    Checked before a command measures anything: the plots are written at the end, and a
    30-minute stress run that then failed on them printed no JSON either.
    """
    if os.path.exists(path) and not os.path.isdir(path):
        return '--plots %s is a file, not a folder' % path
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        return '--plots %s: cannot make it (%s)' % (path, exc.strerror or exc)
    if not os.access(path, os.W_OK | os.X_OK):
        return '--plots %s: cannot write into it' % path
    return None


def main(argv=None):
    """Run one benchmark command; stress and settle exit 1 if a promised case failed."""
    parser = argparse.ArgumentParser(prog='hair_sim_bench', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('command', choices=['accuracy', 'scale', 'skip', 'stress', 'settle',
                                            'node', 'budget', 'hanging', 'style',
                                            'fall', 'viewer', 'jitter', 'materials',
                                            'turn'])
    parser.add_argument('--json', action='store_true', help='print JSON on stdout')
    parser.add_argument('--quick', action='store_true', help='a short run (under a minute)')
    parser.add_argument('--plots', default='bench_out', help='directory for PNG plots')
    parser.add_argument('--model', choices=['anjyo', 'articulated'], default='anjyo',
                        help='the strand model the cases run (stress and settle only)')
    parser.add_argument('--shape-stiffness', type=float, default=0.0,
                        help='the articulated model\'s physics.shape_stiffness (stress and '
                        'settle only)')
    args = parser.parse_args(argv)
    if args.shape_stiffness != 0.0 and (args.command not in ('stress', 'settle')
                                        or args.model != 'articulated'):
        parser.error('--shape-stiffness is for stress and settle with --model articulated')
    try:                                    # (the parameter's own check: range, NaN)
        PhysicsParams().replaced(shape_stiffness=args.shape_stiffness)
    except ValueError as exc:
        parser.error('--shape-stiffness: %s' % exc)
    why = plots_folder_problem(args.plots) if args.command in PLOTTING else None
    if why:
        parser.error(why)
    os.environ.setdefault('NUMBA_NUM_THREADS', '1')
    if args.command == 'accuracy':
        from hair_sim.bench import accuracy
        emit(accuracy.run(args.quick, args.plots), args.json, 'accuracy')
    elif args.command == 'scale':
        from hair_sim.bench import scale
        emit(scale.run(args.quick, args.plots), args.json, 'scale')
    elif args.command == 'node':
        from hair_sim.bench import node
        result = node.run(args.quick)
        print(json.dumps(clean(result), indent=1) if args.json else json.dumps(clean(result)))
    elif args.command == 'budget':
        from hair_sim.bench import budget
        result = budget.run(args.quick)
        print(json.dumps(clean(result), indent=1) if args.json else json.dumps(clean(result)))
    elif args.command == 'hanging':
        from hair_sim.bench import hanging
        emit(hanging.run(args.quick, args.plots), args.json, 'hanging')
    elif args.command == 'settle':
        from hair_sim.bench import settle
        result = settle.run(args.quick, args.model, args.shape_stiffness)
        if args.json:
            print(json.dumps(clean(result), indent=1))
        else:
            emit(result['summary'], False, 'settle')
        failed = [r for r in result['summary'] if r['promised'] and r['not_asleep']]
        if failed:
            cells = ['%s/%s/dt=1/%d (%d of %d)'
                     % (r['style'], r['model'], round(1 / r['dt']), r['not_asleep'], r['runs'])
                     for r in failed]
            print('settle: promised steps where the hair did not always sleep: %s'
                  % ', '.join(cells), file=sys.stderr)
            return 1
    elif args.command == 'style':
        from hair_sim.bench import style_keeping
        emit(style_keeping.run(args.quick), args.json, 'style')
    elif args.command in ('fall', 'materials', 'turn'):
        import importlib.util
        if importlib.util.find_spec('mujoco') is None:
            print('hair_sim_bench %s: MuJoCo is not installed (make setup installs it)'
                  % args.command, file=sys.stderr)
            return 1
        if args.command == 'fall':
            from hair_sim.bench import fall
            emit(fall.run(args.quick, args.plots), args.json, 'fall')
        elif args.command == 'turn':
            from hair_sim.bench import moving_head
            emit(moving_head.run(args.quick, args.plots), args.json, 'turn')
        else:
            from hair_sim.bench import materials
            emit(materials.run(args.quick), args.json, 'materials')
    elif args.command == 'viewer':
        from hair_sim.bench import viewer
        emit(viewer.run(args.quick), args.json, 'viewer')
    elif args.command == 'jitter':
        from hair_sim.bench import jitter
        emit(jitter.run(args.quick), args.json, 'jitter')
    elif args.command == 'skip':
        from hair_sim.bench import skip
        emit(skip.run(args.quick), args.json, 'skip')
    else:
        from hair_sim.bench import stress
        records, smap, failed = stress.run(args.quick, args.plots, args.model,
                                           args.shape_stiffness)
        if args.json:
            print(json.dumps(clean({'cases': records, 'stability_map': smap,
                                    'promised_failures': len(failed)}), indent=1))
        else:
            emit(records, False, 'stress')
            emit(smap, False, 'stability map')
        if failed:
            print('stress: %d promised case(s) failed: %s' % (len(failed), ', '.join(
                '%s/%s/%s/dt=1/%d (%s)' % (r['case'], r['model'], r['integrator'],
                                           round(1 / r['dt']), '; '.join(r['failed_on']))
                for r in failed)), file=sys.stderr)
            return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
