#!/usr/bin/env python3
"""Faster pile protocols against the paper's (h = 2e-4 s, tolerance 1e-3): ensembles of piles run
at other time steps and tolerances, and their observables compared with the paper's ensemble.

    /usr/bin/python3 scripts/protocol_study.py run ROOT --size 1000 --seeds 1-4 \\
        --settings h1e-3,h5e-4,tol3e-3,h1e-3_tol3e-3,paper [--jobs 2] [--relax 1] [--grain-shape dimer]
    /usr/bin/python3 scripts/protocol_study.py analyse ROOT --size 1000 [--grain-shape dimer] \\
        [--reference docs/data/ensemble_runs] [--out docs/data/protocol_study] [--figure docs/figures/protocol_study.png]

``run`` runs one ensemble per setting in ROOT/<setting> (yadecd.runs.ensemble: one thread per pile,
``--jobs`` piles at a time; calling it again resumes). ``analyse`` compares every setting with the
reference at the end of the feed and after the relaxation (yadecd.analysis.protocols: Welch intervals,
differences in units of the seed spread); the reference is the paper-setting runs found in
ROOT/paper plus the stored per-run records of ``--reference`` (runs of the same grain count).
Settings: yadecd.analysis.protocols.SETTINGS. ``--grain-shape`` studies piles of clumps
(yadecd.pile.grains): the runs and the reference are that shape's alone.
"""
import argparse
import json
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))


def main(argv=None):
    from yadecd.runs import ensemble as ens
    from yadecd.analysis import protocols as protocol, ensemble as pea
    from yadecd.pile.grains import SHAPES
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = p.add_subparsers(dest='cmd', required=True)
    r = sub.add_parser('run')
    r.add_argument('root')
    r.add_argument('--size', type=int, default=1000)
    r.add_argument('--seeds', default='1-4')
    r.add_argument('--settings', default='h1e-3,h5e-4,tol3e-3,h1e-3_tol3e-3')
    r.add_argument('--relax', type=float, default=1.0)
    r.add_argument('--jobs', type=int, default=2)
    r.add_argument('--grain-shape', default='sphere', choices=list(SHAPES), help='grains of the piles (yadecd.pile.grains.SHAPES)')
    a = sub.add_parser('analyse')
    a.add_argument('root')
    a.add_argument('--size', type=int, default=1000)
    a.add_argument('--grain-shape', default='sphere', choices=list(SHAPES), help='the piles compared: this shape\'s runs and reference records')
    a.add_argument('--reference', action='append', default=[],
                   help='directory of stored per-run records of the paper setting (default docs/data/ensemble_runs)')
    a.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'protocol_study'))
    a.add_argument('--figure', default=os.path.join(REPO, 'docs', 'figures', 'protocol_study'))
    a.add_argument('--wall-note', default='one thread per pile, two piles at a time on two cores',
                   help='how the wall times were measured (figure subtitle)')
    args = p.parse_args(argv)

    if args.cmd == 'run':
        names = [s for s in args.settings.split(',') if s]
        for name in names:
            if name not in protocol.SETTINGS:
                p.error('unknown setting %r (known: %s)' % (name, ', '.join(protocol.SETTINGS)))
        try:
            seeds = ens.parse_seeds(args.seeds)
        except ValueError as e:
            p.error(str(e))
        if args.size < 1 or args.jobs < 1 or args.relax < 0:
            p.error('--size and --jobs must be positive, --relax >= 0')
        for name in names:
            print('protocol study: setting %s (%s)' % (name, ' '.join(protocol.setting_options(name))), flush=True)
            protocol.plan_and_run(args.root, name, args.size, seeds, args.relax, REPO, jobs=args.jobs,
                                  log=lambda m: print(m, flush=True), grain_shape=args.grain_shape)
            print('\n'.join(ens.status_lines(os.path.join(args.root, name))), flush=True)
        return 0

    if not os.path.isdir(args.root):
        p.error('%s is not a protocol study (it does not exist)' % args.root)
    if not any(os.path.isdir(os.path.join(args.root, name)) for name in protocol.SETTINGS):
        p.error('%s holds no setting of a protocol study (known: %s)' % (args.root, ', '.join(protocol.SETTINGS)))
    refs = args.reference or [os.path.join(REPO, 'docs', 'data', 'ensemble_runs')]
    records = {}
    for name in protocol.SETTINGS:
        d = os.path.join(args.root, name)
        if os.path.isdir(d):
            recs, failed, unfinished = pea.collect(d, os.path.join(d, 'analysis'))
            records[name] = [x for x in recs if x['n_grains'] == args.size and pea.grain_shape(x) == args.grain_shape]
            if failed or unfinished:
                print('%s: failed %s, unfinished %s (left out)' % (name, sorted(failed), unfinished))
    here = {(x['run'], x['epoch']) for x in records.get('paper', [])}
    stored = [x for x in pea.stored_records(refs, here) if protocol.is_reference(x, args.size, args.grain_shape)]
    reference = records.get('paper', []) + stored
    # the paper-setting piles re-run here must reproduce the stored records of the same seeds
    same = []
    for x in records.get('paper', []):
        for d in refs:
            path = os.path.join(d, pea.record_file(x['run'], x['epoch']))
            if os.path.exists(path):
                with open(path) as f:
                    y = json.load(f)
                same.append((x['run'], x['epoch'], all(x.get(k) == y.get(k) for k in protocol.OBSERVABLES)))
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(os.path.dirname(args.figure) or '.', exist_ok=True)
    summary = {'size': args.size, 'reproduced_reference_runs': same, 'settings': {}}
    text = ['# Protocol study: %d grains\n' % args.size,
            'Reference: %d paper-setting runs (%d re-run here, the rest stored records). Re-runs identical to the '
            'stored records: %s.\n' % (len({x['run'] for x in reference}), len({x['run'] for x in records.get('paper', [])}),
                                       ', '.join('%s %s %s' % (r, e, 'yes' if ok else 'NO') for r, e, ok in same) or 'none')]
    walls = {name: protocol.wall_times(os.path.join(args.root, name)) for name in protocol.SETTINGS}
    for epoch in ('feed', 'relaxed'):
        ref = [x for x in reference if x['epoch'] == epoch]
        results = {}
        for name, recs in records.items():
            if name == 'paper':
                continue
            test = [x for x in recs if x['epoch'] == epoch]
            if not test:
                continue
            results[name] = {'n_runs': len(test), 'n_ref': len(ref), 'wall_s': list(walls[name].values()),
                             'compare': protocol.compare(test, ref)}
        if 'paper' in records and walls['paper']:
            results['paper'] = {'n_runs': len(ref), 'n_ref': len(ref), 'wall_s': list(walls['paper'].values()),
                                'compare': protocol.compare(ref, ref)}
        summary['settings'][epoch] = results
        text.append('## %s\n' % ('End of the feed' if epoch == 'feed' else 'After the relaxation'))
        text.append(protocol.table_markdown({k: v for k, v in results.items() if k != 'paper'}, epoch, args.size))
        if results:
            protocol.figure(results, ref, '%s_%s.png' % (args.figure, epoch), epoch, args.size, wall_note=args.wall_note)
    if walls['paper']:
        text.append('Paper setting, wall time per pile here: %.1f min (%d runs).\n'
                    % (sum(walls['paper'].values()) / len(walls['paper']) / 60, len(walls['paper'])))
    protocol.save_json(summary, os.path.join(args.out, 'protocol_study_%d.json' % args.size))
    with open(os.path.join(args.out, 'protocol_study_%d.md' % args.size), 'w') as f:
        f.write('\n'.join(text))
    print('\n'.join(text))
    return 0


if __name__ == '__main__':
    sys.exit(main())
