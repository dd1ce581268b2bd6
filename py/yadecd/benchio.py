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


def sweeps_to(history, thresholds):
    """For each threshold, the first sweep (1-based) after which the residual ``history`` (one
    value per sweep) is at or below it, or None if it never is. The residual of Gauss–Seidel
    with momentum is not monotone: a threshold counts as reached at its first crossing, as the
    solver's stopping test would see it when checked at every sweep."""
    out = []
    for th in thresholds:
        if not th > 0:
            raise ValueError('sweeps_to: thresholds must be positive, not %r' % (th,))
        out.append(next((i + 1 for i, r in enumerate(history) if r <= th), None))
    return out
