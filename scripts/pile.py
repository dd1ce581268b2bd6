"""Build Moreau's 3D sand pile with the Contact Dynamics engine.

    yade -n -x scripts/pile.py [--out DIR] [--n-grains N] [--relax T] [--seed S] [...]
    yade -n -x scripts/pile.py --out DIR --resume        # continue from the last checkpoint
    yade -n -x scripts/pile.py --out NEW --branch-from DIR --tolerance 3e-3   # DIR's state, another solver setting
    yade-batch table.txt scripts/pile.py                  # one pile per table row

Every option defaults to the paper's value (``yadecd.pile.defaults()``: the protocol's
``yadecd.pile.protocol.DEFAULTS`` over the engine's solver defaults; SI units: metres,
seconds, kg/m³). In a ``yade-batch`` table the column names are the option names with
underscores (n_grains, seed, ...), plus ``out`` and YADE's ``description`` (the job name);
values are Python expressions, so strings are quoted::

    description out            n_grains seed
    pileA       'out/pileA'    2000     1
    pileB       'out/pileB'    2000     2

Then run ``scripts/pile_figures.py DIR``.
"""
import argparse
import errno
import os
import signal
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd import pile  # noqa: E402

parser = argparse.ArgumentParser(prog='pile.py', description=__doc__.split('\n')[0])
parser.add_argument('--out', default='out/pile', help='run directory (created)')
parser.add_argument('--resume', action='store_true', help='continue the run in --out from its newest valid checkpoint '
                    '(only --stop-time, --checkpoint-every, --vtk and --parallel-min-contacts may be given anew)')
parser.add_argument('--branch-from', metavar='RUN', default=None,
                    help='start --out as a branch of the run in RUN (from its newest checkpoint) with the solver options '
                    'given here changed (%s), and continue it' % ', '.join(pile.BRANCH_MAY_CHANGE))
parser.add_argument('--overwrite', action='store_true', help='start again in --out even if it holds a run (its files are removed)')
ALL = pile.defaults()
for key, value in ALL.items():
    flag = '--' + key.replace('_', '-')
    if isinstance(value, bool):
        parser.add_argument(flag, dest=key, action=argparse.BooleanOptionalAction, default=None, help="default: %s" % value)
    else:
        parser.add_argument(flag, dest=key, type=type(value), default=None, help='default: %r' % (value,))
args = parser.parse_args(sys.argv[1:])
params = {k: v for k, v in vars(args).items() if k in ALL and v is not None}
out = args.out

if os.environ.get('YADE_BATCH'):
    from yade import utils
    table = dict(ALL, out=out)
    utils.readParamsFromTable(**table)
    from yade.params import table as t
    params = {k: getattr(t, k) for k in ALL}
    out = t.out

if args.resume and args.overwrite:
    parser.error('--resume and --overwrite exclude each other')
if args.branch_from and (args.resume or args.overwrite):
    parser.error('--branch-from starts a new run directory: it excludes --resume and --overwrite')
try:
    p = pile.run(out, resume=args.resume, overwrite=args.overwrite, branch_from=args.branch_from, **params)
except (ValueError, OSError, pile.CheckpointError, pile.RunStateError) as e:
    # every check of pile.run happens before the first step; a full disk stops a run at its next write
    message = str(e)
    if isinstance(e, OSError) and e.errno == errno.ENOSPC:
        message = ('the disk is full (%s); the last checkpoint is intact: free some space and continue with --resume'
                   % e)
    sys.stderr.write('pile.py: error: %s\n' % message)
    sys.stderr.flush()
    os._exit(2)
if p.get('stopped_by'):
    # stopped by SIGTERM/SIGINT after a checkpoint: the conventional 128 + signal number
    print('pile stopped by %s after a checkpoint; continue with --resume (run directory %s)' % (p['stopped_by'], out))
    sys.stdout.flush()
    os._exit(128 + int(getattr(signal, p['stopped_by'])))
print('pile %s: %d grains in %.0f s wall time; run directory %s'
      % ('done' if p['finished'] else 'stopped at t=%.3f s' % p['stop_time'], p['n_grains'], p['wall_time_s'], out))
if os.environ.get('YADE_BATCH'):
    from yade import utils
    utils.waitIfBatch()
