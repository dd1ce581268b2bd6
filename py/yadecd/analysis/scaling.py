"""A model of the slab schedule's solve time on N cores, from its measured schedule.

The slab schedule (pkg/cd/core/Schedule.hpp) runs every sweep as a sequence of stages; the ranges
of a stage share no dynamic body and run on as many threads as there are, each range on one
thread, then all threads meet. On N cores a stage lasts as long as its busiest thread, so a sweep
costs, in contact updates on the critical path,

    C(N) = Σ_stages (contacts of the busiest thread's ranges)   (ranges handed out as OpenMP's static schedule)

and the solve ≈ sweeps · C(N) · t_update + sweeps · stages · t_barrier, with t_update the time of
one contact update measured on one thread (cd_core_bench's ns per contact-sweep) and t_barrier the
cost of one meeting of the threads (one per parallel stage: a stage of one range, or a serial
stage, runs on the calling thread without one). ``cd_core_bench`` reports the schedule as
``stages``: per stage its ranges' contact counts, ' ' between ranges and '|' between stages, and
``s:`` before the ranges of a stage that runs on one thread (too small for a parallel region).
"""


def parse_stages(text):
    """'a b|c||d' -> [[a, b], [c], [], [d]] (contact counts per range, per stage); a serial stage
    's:a b' is one thread's work, [a + b]."""
    if text is None or text.strip() == '':
        raise ValueError('an empty schedule')
    out = []
    for part in text.split('|'):
        part = part.strip()
        serial = part.startswith('s:')
        if serial:
            part = part[2:].strip()
        try:
            ranges = [int(x) for x in part.split()] if part else []
        except ValueError:
            raise ValueError('schedule %r: range sizes must be integers' % text)
        if any(x < 0 for x in ranges):
            raise ValueError('schedule %r: a negative range size' % text)
        out.append([sum(ranges)] if serial and ranges else ranges)
    return out


def critical_path(stages, cores):
    """Contact updates on the critical path of one sweep on ``cores`` cores: per stage the busiest
    thread's share, the ranges handed out as OpenMP's static schedule does (contiguous blocks, the
    first ranges % cores threads one range more), summed over the stages."""
    if cores < 1:
        raise ValueError('cores must be at least 1 (got %r)' % cores)
    total = 0
    for ranges in stages:
        n = len(ranges)
        if n == 0:
            continue
        base, extra = divmod(n, cores)
        start, busiest = 0, 0
        for t in range(min(cores, n)):
            size = base + (1 if t < extra else 0)
            busiest = max(busiest, sum(ranges[start:start + size]))
            start += size
        total += busiest
    return total


def solve_ms(stages, cores, sweeps, ns_per_update, barrier_us=0.0):
    """Predicted solve time [ms] of a step: sweeps · (critical path · t_update + parallel stages · t_barrier),
    a parallel stage being one of several ranges."""
    busy = sum(1 for r in stages if len(r) > 1)
    return sweeps * (critical_path(stages, cores) * ns_per_update * 1e-6 + busy * barrier_us * 1e-3 * (cores > 1))
