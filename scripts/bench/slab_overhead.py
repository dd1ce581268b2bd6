"""What cutting a pile step into slabs costs in Gauss–Seidel sweeps: one saved step (a problem
file, scripts/bench/save_step.py) solved by the core benchmark (build/cd_core_bench, no YADE)
with the slab schedule and 1, 2, 4, ..., 64 slabs, on 1 and 2 threads.

    /usr/bin/python3 scripts/bench/slab_overhead.py STEP.cdp [--slabs 1,2,4,8,16,32,64] [--threads 1,2]
        [--out docs/data/slab_overhead.csv] [--figure docs/figures/slab_overhead.png]

The slab sweep is a domain decomposition with a sequential interface (docs/method.md): every
slab is swept upwards on its own thread, then the contacts of the bodies that straddle a cut.
More slabs mean more parallelism and a larger interface; this measures the sweeps to the step's
tolerance, the interface's share of the contacts (and the part of it that spans more than two
slabs, swept by one thread) and the solve time, and models the solve on 1–64 cores from the
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
    ap.add_argument('--slabs', default='1,2,4,8,16,32,64')
    ap.add_argument('--threads', default='1,2')
    ap.add_argument('--bench', default=os.path.join(REPO, 'build', 'cd_core_bench'))
    ap.add_argument('--cores', default='1,2,4,8,16,32,64', help='core counts of the model')
    ap.add_argument('--barrier-us', type=float, default=3.0, help='the model\'s cost of one meeting of the threads [us]')
    ap.add_argument('--model-out', default=os.path.join(REPO, 'docs', 'data', 'slab_model.csv'))
    ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'slab_overhead.csv'))
    ap.add_argument('--figure', default=os.path.join(REPO, 'docs', 'figures', 'slab_overhead.png'))
    a = ap.parse_args(argv)
    for path, what in ((a.step, 'step file'), (a.bench, 'core benchmark (build it with cmake --build build)')):
        if not os.path.exists(path):
            ap.error('no %s at %s' % (what, path))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, 'bench.csv')
        for threads in [int(t) for t in a.threads.split(',')]:
            for slabs in [int(s) for s in a.slabs.split(',')]:
                env = dict(os.environ, OMP_NUM_THREADS=str(threads))
                proc = subprocess.run([a.bench, a.step, '--schedule', '5', '--slabs', str(slabs), '--k1', '10', '--k2', '40',
                                       '--repeat', '2', '--csv', out], capture_output=True, text=True, env=env)
                if proc.returncode:
                    sys.exit('slab_overhead.py: %s' % (proc.stderr or proc.stdout))
                print(proc.stdout.strip().split('\n')[1].strip(), '| slabs %d, %d thread(s)' % (slabs, threads), flush=True)
        with open(out) as f:
            rows = list(csv.DictReader(f))
    write_csv(a.out, rows)
    model_rows = model(rows, [int(c) for c in a.cores.split(',')], a.barrier_us)
    write_csv(a.model_out, model_rows)
    plot(rows, a.figure, model_rows)
    return 0


def model(rows, cores, barrier_us):
    """Predicted solve time per slab count and core count, at the one-thread cost of a contact
    update measured with one slab (the height order's kernel)."""
    one = [r for r in rows if r['threads'] == '1']
    ref = min(one, key=lambda r: int(r['slabs']))
    t_update = float(ref['ns_per_contact_sweep'])
    out = []
    for r in sorted(one, key=lambda r: int(r['slabs'])):
        stages = scaling.parse_stages(r['stages'])
        for n in cores:
            ms = scaling.solve_ms(stages, n, int(r['sweeps']), t_update, barrier_us)
            out.append(dict(slabs=int(r['slabs']), cores=n, sweeps=int(r['sweeps']), contacts=int(r['contacts']),
                            interface=int(r['interface']), serial=int(r['serial']),
                            critical_path=scaling.critical_path(stages, n), ns_per_update=t_update, barrier_us=barrier_us,
                            model_solve_ms=ms))
    return out


def plot(rows, path, model_rows=()):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(16, 4.2))
    contacts = int(rows[0]['contacts'])
    for threads in sorted({r['threads'] for r in rows}):
        rs = sorted([r for r in rows if r['threads'] == threads], key=lambda r: int(r['slabs']))
        s = [int(r['slabs']) for r in rs]
        if threads == '1':
            a1.semilogx(s, [int(r['sweeps']) for r in rs], 'o-', base=2, label='sweeps to tolerance')
            a1.semilogx(s, [100 * int(r['interface']) / contacts for r in rs], 's--', base=2, label='interface, % of contacts')
            a1.semilogx(s, [100 * int(r.get('serial') or 0) / contacts for r in rs], 'x:', base=2, label='serial (spans > 2 slabs), %')
        a2.semilogx(s, [float(r['solve_ms']) for r in rs], 'o-', base=2, label='measured, %s thread(s)' % threads)
    if model_rows:
        for n in sorted({m['cores'] for m in model_rows}):
            ms = [m for m in model_rows if m['cores'] == n]
            a2.semilogx([m['slabs'] for m in ms], [m['model_solve_ms'] for m in ms], '--', base=2, lw=0.8, label='model, %d cores' % n)
        best = {}
        for m in model_rows:
            if m['cores'] not in best or m['model_solve_ms'] < best[m['cores']]['model_solve_ms']:
                best[m['cores']] = m
        t1 = best[1]['model_solve_ms']
        ns = sorted(best)
        a3.loglog(ns, [t1 / best[n]['model_solve_ms'] for n in ns], 'o-', base=2, label='model, best slab count')
        a3.loglog(ns, ns, 'k:', base=2, label='ideal')
        for n in ns:
            a3.annotate('%d' % best[n]['slabs'], (n, t1 / best[n]['model_solve_ms']), fontsize=7, xytext=(3, -10), textcoords='offset points')
        a3.set_xlabel('cores')
        a3.set_ylabel('solve speed-up over one core')
        a3.set_title('Modelled (numbers: slabs); barrier %.0f us per stage' % model_rows[0]['barrier_us'], fontsize=9)
        a3.legend(fontsize=8)
        a3.grid(True, lw=0.3)
    a1.set_xlabel('slabs')
    a1.set_title('Slab schedule on one step (%d contacts)' % contacts, fontsize=10)
    a1.legend(fontsize=8)
    a1.grid(True, lw=0.3)
    a2.set_xlabel('slabs')
    a2.set_ylabel('solve time of the step [ms]')
    a2.set_title('Solve time (cd_core_bench, this machine) and model', fontsize=10)
    a2.legend(fontsize=7, ncol=2)
    a2.grid(True, lw=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print('wrote', path)


if __name__ == '__main__':
    sys.exit(main())
