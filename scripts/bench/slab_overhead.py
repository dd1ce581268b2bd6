"""What cutting a pile step into slabs, or into columns, costs in Gauss–Seidel sweeps: one saved
step (a problem file, scripts/bench/save_step.py) solved by the core benchmark
(build/cd_core_bench, no YADE) with the slab schedule at 1, 2, 4, ..., 64 slabs and at
slabs × columns (``--slabs 4x4``: four slabs cut into four columns each, ``slabsAcross``), on 1
and 2 threads.

    /usr/bin/python3 scripts/bench/slab_overhead.py STEP.cdp [--slabs 1,2,4,8,16,32,64,2x2,4x4,4x8,8x8] [--threads 1,2]
        [--slabs-own-bodies] [--out docs/data/slab_overhead.csv] [--figure docs/figures/slab_overhead.png]

The slab sweep is a domain decomposition with a sequential interface (docs/method.md): every
slab is swept upwards on its own thread, then the contacts of the bodies that straddle a cut.
More parts mean more parallelism and a larger interface; this measures the sweeps to the step's
tolerance, the interface's share of the contacts (and the part of it that touches three parts or
more) and the solve time, and models the solve on 1–64 cores from the
measured schedule (yadecd.analysis.scaling: the busiest thread of every stage, at the one-thread
cost of a contact update, plus --barrier-us per stage and sweep): docs/scale-out.md reads it.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from yadecd.io import write_csv  # noqa: E402
from yadecd.analysis import scaling  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(prog='slab_overhead.py', description=__doc__.split('\n')[0])
    ap.add_argument('step')
    ap.add_argument('--slabs', default='1,2,4,8,16,32,64,2x2,4x2,4x4,8x4,4x8,8x8',
                    help='comma-separated slab counts; NxM: N slabs cut into M columns each')
    ap.add_argument('--threads', default='1,2')
    ap.add_argument('--bench', default=os.path.join(REPO, 'build', 'cd_core_bench'))
    ap.add_argument('--slabs-own-bodies', action='store_true',
                    help='every body owned by the part holding most of its contacts (slabsOwnBodies): the interface '
                         'is the contacts between two owners (docs/scale-out.md, "Bodies owned by parts")')
    ap.add_argument('--cores', default='1,2,4,8,16,32,64', help='core counts of the model')
    ap.add_argument('--barrier-us', type=float, default=3.0, help='the model\'s cost of one meeting of the threads [us]')
    ap.add_argument('--untimed', action='store_true',
                    help='count sweeps and schedules only (no timing, one thread): for a machine busy with other runs; '
                         'the model then needs --ns-per-update')
    ap.add_argument('--ns-per-update', type=float, default=None,
                    help='the model\'s one-thread cost of a contact update [ns] (default: measured with one slab)')
    ap.add_argument('--model-out', default=os.path.join(REPO, 'docs', 'data', 'slab_model.csv'))
    ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'slab_overhead.csv'))
    ap.add_argument('--figure', default=os.path.join(REPO, 'docs', 'figures', 'slab_overhead.png'))
    a = ap.parse_args(argv)
    if a.untimed and a.ns_per_update is None:
        ap.error('--untimed needs --ns-per-update (a contact update\'s cost measured on an idle machine)')
    if a.ns_per_update is not None and not a.ns_per_update > 0:
        ap.error('--ns-per-update must be positive')
    if a.untimed:
        a.threads = '1'
    for path, what in ((a.step, 'step file'), (a.bench, 'core benchmark (build it with cmake --build build)')):
        if not os.path.exists(path):
            ap.error('no %s at %s' % (what, path))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, 'bench.csv')
        for threads in [int(t) for t in a.threads.split(',')]:
            for slabs, across in parse_parts(a.slabs, ap):
                env = dict(os.environ, OMP_NUM_THREADS=str(threads))
                proc = subprocess.run([a.bench, a.step, '--schedule', '5', '--slabs', str(slabs), '--slabs-across', str(across),
                                       '--slabs-own-bodies', '1' if a.slabs_own_bodies else '0',
                                       '--k1', '10', '--k2', '40', '--repeat', '2', '--time-sweeps', '0' if a.untimed else '1',
                                       '--csv', out], capture_output=True, text=True, env=env)
                if proc.returncode:
                    sys.exit('slab_overhead.py: %s' % (proc.stderr or proc.stdout))
                print(proc.stdout.strip().split('\n')[1].strip(), '| %s, %d thread(s)' % (label(slabs, across), threads), flush=True)
        with open(out) as f:
            rows = list(csv.DictReader(f))
    write_csv(a.out, rows)
    model_rows = model(rows, [int(c) for c in a.cores.split(',')], a.barrier_us, a.ns_per_update)
    write_csv(a.model_out, model_rows)
    plot(rows, a.figure, model_rows, timed=not a.untimed)
    return 0


def parse_parts(text, ap=None):
    """'1,2,4x4' -> [(1, 1), (2, 1), (4, 4)]: slabs and columns per slab."""
    out = []
    for item in text.split(','):
        try:
            slabs, _, across = item.strip().partition('x')
            pair = (int(slabs), int(across or 1))
        except ValueError:
            pair = (0, 0)
        if pair[0] < 1 or pair[1] < 1 or pair[0] * pair[1] > 64:
            msg = '--slabs: %r is not N or NxM with N, M >= 1 and N*M <= 64' % item
            if ap:
                ap.error(msg)
            raise ValueError(msg)
        out.append(pair)
    return out


def label(slabs, across):
    return '%d slabs' % slabs if across == 1 else '%dx%d columns' % (slabs, across)


def parts(r):
    """(slabs, columns per slab) of a row of cd_core_bench's CSV (rows before columns: 1)."""
    return int(r['slabs']), int(r.get('slabs_across') or 1)


def model(rows, cores, barrier_us, ns_per_update=None):
    """Predicted solve time per decomposition and core count, at the one-thread cost of a contact
    update ``ns_per_update``, or else as measured with one slab (the height order's kernel)."""
    one = [r for r in rows if r['threads'] == '1']
    ref = min(one, key=lambda r: parts(r)[0] * parts(r)[1])
    t_update = ns_per_update if ns_per_update is not None else float(ref['ns_per_contact_sweep'])
    out = []
    for r in sorted(one, key=lambda r: (parts(r)[0] * parts(r)[1], parts(r)[1])):
        stages = scaling.parse_stages(r['stages'])
        slabs, across = parts(r)
        for n in cores:
            ms = scaling.solve_ms(stages, n, int(r['sweeps']), t_update, barrier_us)
            out.append(dict(slabs=slabs, slabs_across=across, parts=slabs * across, cores=n, sweeps=int(r['sweeps']),
                            contacts=int(r['contacts']), interface=int(r['interface']), wide=int(r['wide']),
                            critical_path=scaling.critical_path(stages, n), ns_per_update=t_update, barrier_us=barrier_us,
                            model_solve_ms=ms, model_sweep_us=1e3 * ms / int(r['sweeps']),
                            sweep_speedup=int(r['contacts']) * t_update * 1e-3 / (1e3 * ms / int(r['sweeps']))))
    return out


def plot(rows, path, model_rows=(), timed=True):
    """Left: sweeps, interface and wide share against the parts (slabs: lines; columns: squares,
    one per slabs x columns). Middle: the measured solve times, or (untimed) the modelled time of
    one sweep at 2, 8, 32 and 64 cores. Right: the modelled speed-up of one sweep over one core,
    the best decomposition at each core count, slabs only and slabs or columns (the sweeps to the
    tolerance move with the order by ±20 % on one step and by a few % over several: they are
    left out of this panel)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(16, 4.6))
    contacts = int(rows[0]['contacts'])
    one = [r for r in rows if r['threads'] == '1']
    for kind, pick, style in (('slabs', lambda r: parts(r)[1] == 1, dict(marker='o', ls='-')),
                              ('columns', lambda r: parts(r)[1] > 1, dict(marker='s', ls='none'))):
        rs = sorted([r for r in one if pick(r)], key=lambda r: parts(r)[0] * parts(r)[1])
        if not rs:
            continue
        n = [parts(r)[0] * parts(r)[1] for r in rs]
        a1.semilogx(n, [int(r['sweeps']) for r in rs], base=2, color='C0', label='sweeps to tolerance, %s' % kind, **style)
        a1.semilogx(n, [100 * int(r['interface']) / contacts for r in rs], base=2, color='C1', label='interface, %% of contacts, %s' % kind, **style)
        a1.semilogx(n, [100 * int(r.get('wide') or 0) / contacts for r in rs], base=2, color='C2',
                    label='touching > 2 parts, %%, %s' % kind, **style)
        if timed:
            for threads in sorted({r['threads'] for r in rows}):
                rt = sorted([r for r in rows if r['threads'] == threads and pick(r)], key=lambda r: parts(r)[0] * parts(r)[1])
                a2.semilogx([parts(r)[0] * parts(r)[1] for r in rt], [float(r['solve_ms']) for r in rt], base=2,
                            label='measured, %s, %s thread(s)' % (kind, threads), **style)
    if model_rows and not timed:  # the machine was busy: the model's time of one sweep
        for i, n in enumerate(c for c in (2, 8, 32, 64) if any(m['cores'] == c for m in model_rows)):
            ms = sorted([m for m in model_rows if m['cores'] == n], key=lambda m: m['parts'])
            for kind, pick, style in (('slabs', lambda m: m['slabs_across'] == 1, dict(marker='o', ls='-')),
                                      ('columns', lambda m: m['slabs_across'] > 1, dict(marker='s', ls='none'))):
                sub = [m for m in ms if pick(m)]
                if sub:
                    a2.semilogx([m['parts'] for m in sub], [m['model_sweep_us'] for m in sub], base=2, color='C%d' % i, ms=4,
                                label='%s, %d cores' % (kind, n), **style)
    if model_rows:
        ns = sorted({m['cores'] for m in model_rows})
        for kind, pick, mark in (('slabs only', lambda m: m['slabs_across'] == 1, 'o-'), ('slabs or columns', lambda m: True, 's-')):
            sub = {}
            for m in model_rows:
                if pick(m) and (m['cores'] not in sub or m['sweep_speedup'] > sub[m['cores']]['sweep_speedup']):
                    sub[m['cores']] = m
            a3.loglog(ns, [sub[n]['sweep_speedup'] for n in ns], mark, base=2, label='model, best %s' % kind)
            for n in ns:
                a3.annotate(label(sub[n]['slabs'], sub[n]['slabs_across']).split()[0], (n, sub[n]['sweep_speedup']), fontsize=7,
                            xytext=(3, -10 if kind == 'slabs only' else 4), textcoords='offset points')
        a3.loglog(ns, ns, 'k:', base=2, label='ideal')
        a3.set_xlabel('cores')
        a3.set_ylabel('speed-up of one sweep over one core')
        a3.set_title('Modelled on this step (labels: slabs, or slabs x columns);\nbarrier %.0f us per parallel stage'
                     % model_rows[0]['barrier_us'], fontsize=9)
        a3.legend(fontsize=8)
        a3.grid(True, lw=0.3)
    a1.set_xlabel('parts (slabs, or slabs x columns)')
    a1.set_title('Slab and column schedules on one step (%d contacts)' % contacts, fontsize=10)
    a1.legend(fontsize=7)
    a1.grid(True, lw=0.3)
    a2.set_xlabel('parts (slabs, or slabs x columns)')
    if timed:
        a2.set_ylabel('solve time of the step [ms]')
        a2.set_title('Solve time (cd_core_bench, this machine: %s cores)' % (os.cpu_count() or '?'), fontsize=10)
    else:
        a2.set_ylabel('modelled time of one sweep [us]')
        a2.set_title('Modelled (not measured: the machine was busy);\n%.0f ns per update, measured idle' % model_rows[0]['ns_per_update'],
                     fontsize=9)
    a2.legend(fontsize=7, ncol=2)
    a2.grid(True, lw=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print('wrote', path)


if __name__ == '__main__':
    sys.exit(main())
