#!/usr/bin/env python3
"""A CD step on one and two threads, alone and beside another busy process (oversubscription).

    python3 scripts/bench/oversubscription.py PROBLEM.cdp [--rounds 2] [--repeat 3]
        [--out docs/data/oversubscription.csv]

Runs build/cd_core_bench on a saved step (scripts/bench/save_step.py) in eight settings, rounds
interleaved, each alone and beside one busy-looping process (what a second simulation, a build or
a benchmark does to a two-core machine): 1 thread; 2 threads at any size (parallelMinContacts 0);
the same with OMP_WAIT_POLICY=passive; 2 threads with the default parallelMinContacts (serial
sweeps below 2 000 contacts; 10 000 when docs/data/oversubscription.csv was measured). Prints and saves the step's solve +
correction time [ms] per setting (best of --repeat inside each run; median over rounds) and its
ratio to one thread alone. Nothing else may run meanwhile (pause long jobs with kill -STOP).
"""
import argparse
import datetime
import os
import re
import statistics
import subprocess
import sys
import time
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from yadecd.io import write_csv  # noqa: E402
ALWAYS = ['--parallel-min-contacts', '0']     # threads at any size (the engine before parallelMinContacts)
SETTINGS = [  # name, threads, busy competitor, extra environment, cd_core_bench options
    ('1 thread, alone', 1, False, {}, []),
    ('2 threads, alone', 2, False, {}, ALWAYS),
    ('2 threads passive, alone', 2, False, {'OMP_WAIT_POLICY': 'passive'}, ALWAYS),
    ('2 threads default threshold, alone', 2, False, {}, []),
    ('1 thread, beside a busy process', 1, True, {}, []),
    ('2 threads, beside a busy process', 2, True, {}, ALWAYS),
    ('2 threads passive, beside a busy process', 2, True, {'OMP_WAIT_POLICY': 'passive'}, ALWAYS),
    ('2 threads default threshold, beside a busy process', 2, True, {}, []),
]
LINE = re.compile(r'solve ([0-9.]+) ms, correct ([0-9.]+) ms')


def step_ms(problem, threads, extra, options, repeat):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    env.pop('OMP_WAIT_POLICY', None)
    env.update(extra)
    out = subprocess.run([os.path.join(REPO, 'build', 'cd_core_bench'), problem, '--time-sweeps', '0', '--repeat', str(repeat)] + options,
                         env=env, capture_output=True, text=True, check=True).stdout
    m = LINE.search(out)
    if not m:
        raise RuntimeError('cd_core_bench printed no step time:\n' + out)
    return float(m.group(1)) + float(m.group(2))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('problem')
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'oversubscription.csv'))
    a = ap.parse_args()
    if not os.path.exists(a.problem):
        ap.error('%s: no such problem file' % a.problem)
    times = {s[0]: [] for s in SETTINGS}
    for rnd in range(a.rounds):
        for name, threads, busy, extra, options in SETTINGS:
            spinner = subprocess.Popen([sys.executable, '-c', 'while True: pass']) if busy else None
            try:
                if spinner:
                    time.sleep(0.5)
                times[name].append(step_ms(a.problem, threads, extra, options, a.repeat))
            finally:
                if spinner:
                    spinner.kill()
                    spinner.wait()
            print('round %d  %-52s %9.1f ms' % (rnd + 1, name, times[name][-1]), flush=True)
    base = statistics.median(times[SETTINGS[0][0]])
    rows = []
    for name, threads, busy, extra, options in SETTINGS:
        med = statistics.median(times[name])
        rows.append(dict(date=datetime.date.today().isoformat(), problem=os.path.basename(a.problem), setting=name,
                         threads=threads, busy_competitor=busy, omp_wait_policy=extra.get('OMP_WAIT_POLICY', 'default'),
                         parallel_min_contacts='0' if options else 'default',
                         step_ms_median='%.1f' % med, rounds=' '.join('%.1f' % t for t in times[name]),
                         over_1_thread_alone='%.2f' % (med / base)))
        print('%-52s median %9.1f ms   x%.2f of 1 thread alone' % (name, med, med / base))
    write_csv(a.out, rows)


if __name__ == '__main__':
    main()
