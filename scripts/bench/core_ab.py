"""Two builds of the solver core's benchmark (build/cd_core_bench) timed in one run on saved steps,
rounds interleaved so that the machine's drift hits both alike; prints and saves, per step file,
option set and thread count, the median of every figure per build and the ratio new/old.

    /usr/bin/python3 scripts/bench/core_ab.py --old OLD/cd_core_bench --new build/cd_core_bench \\
        STEP.cdp [STEP.cdp ...] [--rounds 3] [--threads 1,2] [--variants 'default;--momentum 0']
        [--out docs/data/core_ab_steps.csv]

Saved steps come from scripts/bench/save_step.py. Each variant is a string of cd_core_bench
options; the options a build does not know make that build's run fail (say so with a variant the
old build supports). Figures: sweeps, contact updates, solve and correction ms of the step at the
file's tolerance, and ns per contact-sweep (forced 20- and 80-sweep solves). A ratio below 1 means
the new build is faster. Run it on an idle machine: the numbers are only comparable within one run.
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd
from yadecd.io import write_csv  # noqa: E402

FIGURES = (('sweeps', r'(\d+) sweeps \('),
           ('contact_updates', r'; (\d+) contact updates'),
           ('solve_ms', r'solve ([0-9.]+) ms'),
           ('correct_ms', r'correct ([0-9.]+) ms'),
           ('ns_per_contact_sweep', r'time per contact-sweep: ([0-9.]+) ns'),
           ('residual_checks', r'(\d+) residual checks'))


def parse(text):
    """The figures of one cd_core_bench report (a dict; absent figures are left out)."""
    out = {}
    for name, pattern in FIGURES:
        m = re.search(pattern, text)
        if m:
            out[name] = float(m.group(1))
    m = re.search(r'(\d+) contacts;', text)
    if m:
        out['contacts'] = int(m.group(1))
    return out


def run(binary, step, variant, threads):
    opts = [] if variant == 'default' else variant.split()
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    cmd = [binary, step, '--k1', '20', '--k2', '80', '--repeat', '2'] + opts
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        sys.exit('core_ab.py: %s failed:\n%s' % (' '.join(cmd), proc.stdout[-2000:] + proc.stderr[-2000:]))
    return parse(proc.stdout)


def main(argv=None):
    ap = argparse.ArgumentParser(prog='core_ab.py', description=__doc__.split('\n')[0])
    ap.add_argument('steps', nargs='+')
    ap.add_argument('--old', required=True)
    ap.add_argument('--new', required=True)
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--threads', default='1')
    ap.add_argument('--variants', default='default', help="';'-separated option strings ('default': the file's options)")
    ap.add_argument('--out', default=None)
    args = ap.parse_args(argv)
    for name in ('old', 'new'):
        if not os.access(getattr(args, name), os.X_OK):
            ap.error('--%s %s: not an executable' % (name, getattr(args, name)))
    for s in args.steps:
        if not os.path.exists(s):
            ap.error('no step file %s' % s)
    if args.rounds < 1:
        ap.error('need --rounds >= 1')
    threads = [int(t) for t in args.threads.split(',')]
    variants = [v.strip() for v in args.variants.split(';') if v.strip()]
    values = {}
    for rnd in range(args.rounds):
        for build in (('old', 'new') if rnd % 2 == 0 else ('new', 'old')):
            for step in args.steps:
                for variant in variants:
                    for t in threads:
                        figs = run(getattr(args, build), step, variant, t)
                        slot = values.setdefault((step, variant, t), {'old': {}, 'new': {}, 'contacts': figs.get('contacts')})
                        for k, v in figs.items():
                            slot[build].setdefault(k, []).append(v)
        print('round %d/%d done' % (rnd + 1, args.rounds), flush=True)
    rows = []
    for (step, variant, t), slot in values.items():
        for name, _ in FIGURES:
            if name not in slot['old'] or name not in slot['new']:
                continue
            mo, mn = statistics.median(slot['old'][name]), statistics.median(slot['new'][name])
            rows.append(dict(step=os.path.basename(step),
                             contacts=slot['contacts'], variant=variant, threads=t, rounds=args.rounds, figure=name,
                             old_median=mo, new_median=mn, ratio_new_old=(mn / mo if mo else float('nan'))))
    print('%-16s %-22s %2s  %-22s %12s %12s %7s' % ('step', 'variant', 'th', 'figure', 'old', 'new', 'new/old'))
    for r in rows:
        print('%-16s %-22s %2d  %-22s %12.4g %12.4g %7.3f' % (r['step'], r['variant'][:22], r['threads'], r['figure'],
                                                              r['old_median'], r['new_median'], r['ratio_new_old']))
    if args.out:
        write_csv(args.out, rows)


if __name__ == '__main__':
    main()
