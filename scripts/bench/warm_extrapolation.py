#!/usr/bin/env python3
"""Does a warm start extrapolated from two steps save sweeps? For consecutive saved steps
(save_step.py ... --count N --spacing 1: STEM_0.cdp ... STEM_{N-1}.cdp), step k is solved from its
own warm start (the impulses of step k-1) and from w_k + a (w_k - w_{k-1}) for each ``--alpha``
(a contact's impulse two steps back is the warm start of step k-1's file; contacts new or open at
either step keep their own warm start), and the sweeps to the file's tolerance are counted by the
core benchmark. Sweep counts do not depend on the machine's load, so this needs no quiet machine.

    /usr/bin/python3 scripts/bench/warm_extrapolation.py /work/steps/consec/s2c /work/steps/consec/f60c \\
        --count 6 --alpha 0.5,1 --bench build/cd_core_bench --csv docs/data/warm_extrapolation.csv
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..', 'py'))  # this checkout's yadecd

from yadecd.io import write_csv  # noqa: E402
from sweep_counts import sweeps  # noqa: E402  (this directory's)

#: the warm start's fields on a problem file's contact line (pkg/cd/core/ProblemFile.hpp)
WARM = slice(33, 36)


def warm_starts(path):
    """{(b1, b2): warm start (3 floats)} of a problem file's contacts."""
    out = {}
    with open(path) as f:
        for line in f:
            if line.startswith('contact '):
                t = line.split()
                out[(t[1], t[2])] = [float(x) for x in t[WARM]]
    return out


def extrapolate(prev, cur, out, alpha):
    """Write ``cur`` to ``out`` with every contact's warm start w extrapolated to w + alpha (w - w_prev)
    when the contact has a non-zero warm start in both files. Returns (contacts, extrapolated)."""
    before = warm_starts(prev)
    n = m = 0
    with open(cur) as f, open(out, 'w') as g:
        for line in f:
            if line.startswith('contact '):
                t = line.split()
                w, p = [float(x) for x in t[WARM]], before.get((t[1], t[2]))
                n += 1
                if p is not None and any(p) and any(w):
                    t[WARM] = [repr(w[i] + alpha * (w[i] - p[i])) for i in range(3)]
                    line = ' '.join(t) + '\n'
                    m += 1
            g.write(line)
    return n, m


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('stems', nargs='+', help='for each pile, the saved steps STEM_0.cdp, STEM_1.cdp, ...')
    ap.add_argument('--count', type=int, required=True, help='consecutive steps per stem')
    ap.add_argument('--alpha', default='0.5,1', help='extrapolation factors, comma-separated')
    ap.add_argument('--bench', default='build/cd_core_bench')
    ap.add_argument('--threads', type=int, default=1)
    ap.add_argument('--csv', required=True)
    args = ap.parse_args()
    alphas = [float(a) for a in args.alpha.split(',') if a.strip()]
    files = {stem: ['%s_%d.cdp' % (stem, k) for k in range(args.count)] for stem in args.stems}
    missing = [f for fs in files.values() for f in fs if not os.path.exists(f)]
    if missing or args.count < 2:
        sys.exit('need at least two consecutive saved steps per stem; missing: %s' % ', '.join(missing))
    rows = []
    with tempfile.TemporaryDirectory(prefix='cd-warm-') as tmp:
        out = os.path.join(tmp, 'x.cdp')
        for stem, fs in files.items():
            for k in range(1, args.count):
                row = dict(step=os.path.basename(fs[k]), sweeps=sweeps(args.bench, fs[k], [], args.threads))
                for a in alphas:
                    n, m = extrapolate(fs[k - 1], fs[k], out, a)
                    row.update({'contacts': n, 'extrapolated': m, 'sweeps_alpha_%g' % a: sweeps(args.bench, out, [], args.threads)})
                print(', '.join('%s %s' % kv for kv in row.items()), flush=True)
                rows.append(dict(row, threads=args.threads))
            part = [r for r in rows if r['step'].startswith(os.path.basename(stem) + '_')]
            total = {k: sum(r[k] for r in part) for k in part[0] if k.startswith('sweeps')}
            print('%s total: ' % os.path.basename(stem) + ', '.join('%s %d (%.3f)' % (k, v, v / total['sweeps']) for k, v in total.items()))
    write_csv(args.csv, rows)       # with the machine, commit and date


if __name__ == '__main__':
    main()
