"""Plane shear between rough walls at controlled normal stress, periodic in x and y, by CD or by
YADE's MD (yadecd.compare.shear): μ(I) and φ(I) of frictional spheres (μ = 0.5).

    scripts/yade -n -x scripts/shear_rheology.py --out out/shear --method cd --I 0.1,0.03,0.01,0.003
    scripts/yade -n -x scripts/shear_rheology.py --out out/shear --method md --I 0.1,0.03,0.01
    /usr/bin/python3 scripts/shear_figures.py out/shear          # table + figure

The packing (--n spheres, --seed) is made once, by CD, and kept as OUT/packing_n<N>_s<seed>.yade.gz
(a YADE archive, with a .json beside it); every run of either method starts from it. Each run writes OUT/<method>_I<I>_n<N>_s<seed>.csv (the
samples, written as they come), a checkpoint every 20 samples (<stem>.ckpt.json and the scene's
archive <stem>.ckpt_<samples>.yade.gz) and, when it ends, a .json beside it (its settings and the
steady-state means with batch-means error bars). Running the same command again skips the runs
whose .json exists and resumes an interrupted run from its checkpoint (the same bits as an
uninterrupted run, for CD); with --extend and a larger --strain, a finished run continues from
its final checkpoint and its record is remade over the longer window.
"""
import argparse
import glob
import json
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.analysis import rheology  # noqa: E402
from yadecd.compare import shear  # noqa: E402
from yadecd.io import append_csv, provenance, write_csv, write_json_atomic  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('--out', required=True)
parser.add_argument('--method', choices=('cd', 'md'), required=True)
parser.add_argument('--I', default='0.1,0.03,0.01,0.003', help='inertial numbers, comma-separated')
parser.add_argument('--n', type=int, default=2000, help='spheres in the cell')
parser.add_argument('--seed', type=int, default=1)
parser.add_argument('--strain', type=float, default=3.0, help='top wall travel over the gap in each run')
parser.add_argument('--skip-strain', type=float, default=1.0, help='strain discarded as the transient')
CD, MD = rheology.PROTOCOL['cd'], rheology.PROTOCOL['md']
parser.add_argument('--dgamma', type=float, default=CD['dgamma'], help='CD: shear strain per step (h = dgamma/γ̇, at most dt_max·t_i)')
parser.add_argument('--dt-max', type=float, default=CD['dt_max'], help='CD: largest time step over the inertial time t_i')
parser.add_argument('--tolerance', type=float, default=CD['tolerance'], help='CD: solver tolerance (as the pile protocol)')
parser.add_argument('--en-cd', type=float, default=CD['en_cd'], help="CD: normal restitution (Moreau's law)")
parser.add_argument('--young-over-p', type=float, default=MD['young_over_p'], help="MD: Young's modulus over p")
parser.add_argument('--en-md', type=float, default=MD['en_md'], help='MD: normal restitution')
parser.add_argument('--es-md', type=float, default=MD['es_md'], help='MD: tangential restitution (1: no tangential viscous damping)')
parser.add_argument('--safety', type=float, default=MD['safety'], help="MD: time step over YADE's P-wave time step")
parser.add_argument('--tag', default='', help='suffix of the run files (<method>_I<I>_n<N>_s<seed>_<tag>), for runs off the '
                    'reference protocol or of another travel; the analysis tells variants by their options, not by the tag')
parser.add_argument('--overwrite', action='store_true', help='redo runs whose results exist (their files removed first)')
parser.add_argument('--extend', action='store_true', help='continue finished runs from their final checkpoint to a larger --strain')
args = parser.parse_args(sys.argv[1:])

if args.tag and not args.tag.replace('-', '').replace('.', '').replace('_', '').isalnum():
    sys.exit('--tag must be letters, digits, ".", "-" or "_", not %r' % args.tag)
for value, name in ((args.n, '--n'), (args.strain, '--strain'), (args.dgamma, '--dgamma'), (args.dt_max, '--dt-max')):
    if value <= 0:
        sys.exit('%s must be positive, not %r' % (name, value))
if not 0 <= args.skip_strain < args.strain:
    sys.exit('--skip-strain must be in [0, --strain)')
os.makedirs(args.out, exist_ok=True)


def log(msg):
    """Print ``msg`` at once (long runs are followed in their logs)."""
    print(msg, flush=True)


pack_path = os.path.join(args.out, 'packing_n%d_s%d.yade.gz' % (args.n, args.seed))
if os.path.exists(pack_path):
    log('packing: %s' % pack_path)
else:
    made = shear.packing(pack_path + '.tmp.yade.gz', n=args.n, seed=args.seed, log=log)
    os.replace(pack_path + '.tmp.yade.gz', pack_path)
    write_json_atomic(pack_path[:-len('.yade.gz')] + '.json', dict(made, **provenance()))
    log('packing: made, gap %.2f mm, phi %.4f, %d steps -> %s' % (made['gap'] * 1e3, made['phi'], made['steps'], pack_path))

options = dict(dgamma=args.dgamma, dt_max=args.dt_max, tolerance=args.tolerance, en_cd=args.en_cd) if args.method == 'cd' else \
    dict(young_over_p=args.young_over_p, en_md=args.en_md, es_md=args.es_md, safety=args.safety)
fields = list(shear.SAMPLE_FIELDS)


def remove_run(stem):
    """A run's files: its samples, record, checkpoint bookkeeping and archives."""
    for path in [stem + e for e in ('.csv', '.json', '.ckpt.json')] + glob.glob(glob.escape(stem) + '.ckpt_*.yade.gz'):
        if os.path.exists(path):
            os.remove(path)


def rows_to_resume(stem, samples):
    """The first ``samples`` rows of the run's samples file, which is rewritten with only them
    (rows measured after the checkpoint are measured again)."""
    rows = [tuple(r[k] for k in fields) for r in rheology.read_samples(stem + '.csv')]
    if len(rows) < samples:
        sys.exit('%s.csv has %d rows, its checkpoint %d: the run cannot be resumed (use --overwrite)' % (stem, len(rows), samples))
    rows = rows[:samples]
    if rows:
        write_csv(stem + '.csv', [dict(zip(fields, row)) for row in rows], log=lambda m: None, stamp=False)
    else:
        append_csv(stem + '.csv', None, fields, start=True, stamp=False)
    return rows


for I in [float(x) for x in args.I.split(',') if x.strip()]:
    stem = os.path.join(args.out, '%s_I%g_n%d_s%d' % (args.method, I, args.n, args.seed) + ('_' + args.tag if args.tag else ''))
    if args.overwrite:
        remove_run(stem)
    ckpt = shear.checkpoint_state(stem)
    if os.path.exists(stem + '.json'):
        with open(stem + '.json') as f:
            travel = json.load(f)['strain']
        if not (args.extend and args.strain > travel):
            log('%s: done (travel %g), skipped' % (stem, travel))
            continue
        if ckpt is None:
            sys.exit('%s: no checkpoint to extend the run from (runs made before checkpoints; use --overwrite)' % stem)
    done_rows = rows_to_resume(stem, ckpt['samples']) if ckpt else []

    def keep(row, _stem=stem):
        append_csv(_stem + '.csv', dict(zip(fields, row)), fields, start=not os.path.exists(_stem + '.csv'), stamp=False)

    info, rows = shear.run(pack_path, args.method, I, strain=args.strain, log=log, on_sample=keep, checkpoint=stem,
                           done_rows=done_rows, **options)
    summary = shear.summarise(rows, info['d'], info['rho'], info['p'], args.skip_strain)
    record = dict(info, options=options, summary=summary, packing=pack_path, seed=args.seed, **provenance())
    write_json_atomic(stem + '.json', record)
    s = record['summary']
    log('%s: mu %.4f ± %.4f, phi %.4f ± %.4f, I %.4g, wall stress %.1f Pa, %.0f s' % (
        stem, s['mu']['mean'], s['mu']['sem'], s['phi']['mean'], s['phi']['sem'], s['I']['mean'], s['normal_stress']['mean'],
        info['wall_s']))
print(json.dumps({'done': args.out}))
