"""One of YADE's example scripts, headless, under Contact Dynamics (its soft engines replaced by
yadecd.engines()) or as written (MD), within a step budget (yadecd.compare.examples).

    scripts/yade -n -x scripts/example_under_cd.py EXAMPLE.py --method cd --steps 20000 --json OUT.json

The example runs from its own directory (some read files beside them). Writes OUT.json: status
('ran' or 'failed'), the error, what the conversion dropped, steps, wall time and the end state.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.compare.examples import ExampleRun  # noqa: E402
from yadecd.io import write_json_atomic  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('example')
parser.add_argument('--method', choices=('cd', 'md'), default='cd')
parser.add_argument('--steps', type=int, default=5000)
parser.add_argument('--json', required=True)
args = parser.parse_args(sys.argv[1:])
out = os.path.abspath(args.json)
example = os.path.abspath(args.example)
if not os.path.isfile(example):
    sys.exit('no example script at %s' % example)
os.chdir(os.path.dirname(example))
result = ExampleRun(example, args.method, args.steps).execute()
write_json_atomic(out, result)
print('%s %s: %s after %d steps in %.1f s %s' % (os.path.basename(example), args.method, result['status'], result['steps'],
                                                result['wall_s'], result['error']), flush=True)
os._exit(0)   # some examples leave threads or GUI hooks behind
