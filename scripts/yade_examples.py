"""YADE's example scripts under CD and as written (MD), side by side: which run under
yadecd.engines(), which do not and why (yadecd.compare.examples.EXAMPLES).

    /usr/bin/python3 scripts/yade_examples.py [--src EXAMPLES_DIR] [--out out/examples] [--only NAME] [--docs]

EXAMPLES_DIR defaults to the examples of the YADE tree the set-up fetched
(~/.cache/yade-cd/src/trunk-<version>/examples). Each example runs twice (one YADE process per run,
headless, a time limit of --timeout seconds each), with the same time step and step budget; runs
whose JSON exists are skipped (--overwrite redoes them). A script that waits for the keyboard
(input()) gets Enter. Writes OUT/examples.csv and
OUT/examples.md (the table); --docs copies both to docs/data/.
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.compare.examples import EXAMPLES  # noqa: E402
from yadecd.io import write_csv  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))


def default_src():
    """The examples directory of the YADE source the set-up fetched, or None."""
    found = sorted(glob.glob(os.path.expanduser('~/.cache/yade-cd/src/trunk-*/examples')))
    return found[-1] if found else None


def run_one(example, method, steps, out_json, timeout):
    """Run one example by ``method`` in a YADE process of its own (``example_under_cd.py``), within
    ``timeout`` seconds; returns its record (status, error, end state)."""
    cmd = [os.path.join(REPO, 'scripts', 'yade'), '-j1', '-n', '-x', os.path.join(REPO, 'scripts', 'example_under_cd.py'),
           example, '--method', method, '--steps', str(steps), '--json', out_json]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, input='\n' * 1000)   # Enter to any prompt
    except subprocess.TimeoutExpired:
        return dict(status='failed', error='over the time limit of %d s' % timeout, steps=None)
    if os.path.exists(out_json):
        with open(out_json) as f:
            return json.load(f)
    tail = (p.stderr or p.stdout).strip().splitlines()[-1:] or ['no output']
    return dict(status='failed', error='YADE exited with %d: %s' % (p.returncode, tail[0][:200]), steps=None)


def fmt(x, spec='%.3g'):
    """``spec % x``, or a dash for a missing value."""
    return '–' if x is None or x != x else spec % x


def table(rows):
    """The markdown table of docs/compare.md: one row per example, CD beside MD."""
    lines = ['| example | what it uses | CD | MD | steps (CD / MD) | kinetic energy CD / MD [J] | mean height CD / MD [m] | CD notes and errors |',
             '| --- | --- | --- | --- | --- | --- | --- | --- |']
    for r in rows:
        cd, md = r['cd'], r['md']
        notes = '; '.join(cd.get('notes') or []) + ((' — ' if cd.get('notes') else '') + cd['error'] if cd.get('error') else '')
        lines.append('| `%s` | %s | %s | %s | %s / %s | %s / %s | %s / %s | %s |' % (
            r['example'], r['what'], cd['status'], md['status'], cd.get('steps'), md.get('steps'),
            fmt(cd.get('kinetic')), fmt(md.get('kinetic')), fmt(cd.get('mean_z'), '%.4g'), fmt(md.get('mean_z'), '%.4g'),
            notes.replace('|', '/') or '–'))
    return '\n'.join(lines) + '\n'


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--src', default=default_src())
    parser.add_argument('--out', default=os.path.join(REPO, 'out', 'examples'))
    parser.add_argument('--only', default='', help='run only examples whose path contains this')
    parser.add_argument('--timeout', type=int, default=900)
    parser.add_argument('--overwrite', action='store_true')
    parser.add_argument('--docs', action='store_true')
    args = parser.parse_args()
    if args.timeout <= 0:
        parser.error('--timeout must be a positive number of seconds (got %d)' % args.timeout)
    if args.only and not any(args.only in rel for rel, _, _ in EXAMPLES):
        parser.error('--only %r matches no example (%s)' % (args.only, ', '.join(rel for rel, _, _ in EXAMPLES)))
    if not args.src or not os.path.isdir(args.src):
        sys.exit('no YADE examples directory (run scripts/setup.sh, or give --src)')
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for rel, what, steps in EXAMPLES:
        if args.only and args.only not in rel:
            continue
        row = dict(example=rel, what=what)
        for method in ('cd', 'md'):
            out_json = os.path.join(args.out, rel.replace('/', '__') + '.%s.json' % method)
            if os.path.exists(out_json) and not args.overwrite:
                with open(out_json) as f:
                    row[method] = json.load(f)
            else:
                row[method] = run_one(os.path.join(args.src, rel), method, steps, out_json, args.timeout)
                if not os.path.exists(out_json):
                    with open(out_json, 'w') as f:
                        json.dump(row[method], f)
            print('%-45s %s: %-6s %s' % (rel, method, row[method]['status'], row[method].get('error', '')), flush=True)
        rows.append(row)
    flat = [dict(example=r['example'], what=r['what'], method=m, status=r[m]['status'], error=r[m].get('error', ''),
                 notes='; '.join(r[m].get('notes') or []), steps=r[m].get('steps'), wall_s=r[m].get('wall_s'),
                 dt=r[m].get('dt'), kinetic=r[m].get('kinetic'), mean_z=r[m].get('mean_z'), contacts=r[m].get('contacts'),
                 max_overlap=r[m].get('max_overlap'), pressure=r[m].get('pressure')) for r in rows for m in ('cd', 'md')]
    write_csv(os.path.join(args.out, 'examples.csv'), flat)
    with open(os.path.join(args.out, 'examples.md'), 'w') as f:
        f.write(table(rows))
    if args.docs:
        for name in ('examples.csv', 'examples.md'):
            shutil.copy(os.path.join(args.out, name), os.path.join(REPO, 'docs', 'data', 'yade_' + name))


if __name__ == '__main__':
    main()
