"""Output of the benchmark scripts (scripts/bench/): one helper, so that every script writes its
numbers the same way. Pure Python: no YADE."""
import csv
import os


def write_csv(path, rows, log=print):
    """Write ``rows`` (dicts with the same keys, in the order of the first) to the CSV file
    ``path``, creating its directory; says where."""
    if not rows:
        raise ValueError('write_csv: no rows to write to %s' % path)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    log('wrote %s' % path)
    return path
