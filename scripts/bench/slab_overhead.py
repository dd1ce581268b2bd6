"""What cutting a pile step into slabs costs in Gauss–Seidel sweeps: one saved step (a problem
file, scripts/bench/save_step.py) solved by the core benchmark (build/cd_core_bench, no YADE)
with the slab schedule and 1, 2, 4, ..., 64 slabs, on 1 and 2 threads.

    /usr/bin/python3 scripts/bench/slab_overhead.py STEP.cdp [--slabs 1,2,4,8,16,32,64] [--threads 1,2]
        [--out docs/data/slab_overhead.csv] [--figure docs/figures/slab_overhead.png]

The slab sweep is a domain decomposition with a sequential interface (docs/method.md): every
slab is swept upwards on its own thread, then the contacts of the bodies that straddle a cut.
More slabs mean more parallelism and a larger interface; this measures the sweeps to the step's
tolerance, the interface's share of the contacts and the solve time (docs/scale-out.md reads it).
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


def main(argv=None):
    ap = argparse.ArgumentParser(prog='slab_overhead.py', description=__doc__.split('\n')[0])
    ap.add_argument('step')
    ap.add_argument('--slabs', default='1,2,4,8,16,32,64')
    ap.add_argument('--threads', default='1,2')
    ap.add_argument('--bench', default=os.path.join(REPO, 'build', 'cd_core_bench'))
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
    plot(rows, a.figure)
    return 0


def plot(rows, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    contacts = int(rows[0]['contacts'])
    for threads in sorted({r['threads'] for r in rows}):
        rs = sorted([r for r in rows if r['threads'] == threads], key=lambda r: int(r['slabs']))
        s = [int(r['slabs']) for r in rs]
        if threads == '1':
            a1.semilogx(s, [int(r['sweeps']) for r in rs], 'o-', base=2, label='sweeps to tolerance')
            a1.semilogx(s, [100 * int(r['interface']) / contacts for r in rs], 's--', base=2, label='interface, % of contacts')
        a2.semilogx(s, [float(r['solve_ms']) for r in rs], 'o-', base=2, label='%s thread(s)' % threads)
    a1.set_xlabel('slabs')
    a1.set_title('Slab schedule on one step (%d contacts)' % contacts, fontsize=10)
    a1.legend(fontsize=8)
    a1.grid(True, lw=0.3)
    a2.set_xlabel('slabs')
    a2.set_ylabel('solve time of the step [ms]')
    a2.set_title('Solve time (cd_core_bench, this machine)', fontsize=10)
    a2.legend(fontsize=8)
    a2.grid(True, lw=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print('wrote', path)


if __name__ == '__main__':
    sys.exit(main())
