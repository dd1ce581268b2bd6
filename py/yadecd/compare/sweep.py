"""CD against YADE's soft-contact MD, side by side: the sweep of ``scripts/compare_cd_md.py``
(the plan of runs, running them with :func:`yadecd.compare.run`, the summary at equal accuracy
and the failure boundaries, and the charts). :func:`main` does what the script's options ask.
"""
import csv
import math
import os
import sys
import time

from yadecd import compare

# ----------------------------------------------------------------------------------------------
# the plan

YOUNG = [1e5, 1e6, 1e7, 1e8, 1e9]
SAFETY = [0.1, 0.3, 0.5, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0]   # > 1: beyond the usual advice, to find where MD fails
SAFETY_160 = [0.3, 0.8, 1.5, 2.0, 3.0]                    # the 160-sphere column: fewer, for CPU time
CD_MAXITER = 1000000
YOUNG_STIFF = [1e10, 1e11]       # glass/steel-like stiffness, dynamic scenes only (cost: dt ∝ 1/sqrt(E))
SAFETY_STIFF = [0.5, 1.0, 2.0]
MAX_STEPS = 2000000              # runs needing more steps than this are left out (CPU budget)
CASES = {
    'incline': [{'regime': 'rolling'}, {'regime': 'slipping'}],
    'column': [{'n': 10}, {'n': 40}, {'n': 160}],
    'mass_ratio': [{'ratio': 10}, {'ratio': 100}, {'ratio': 1000}],
    'binary': [{'en': 1.0}, {'en': 0.5}],
    'projectile': [{'speed': 1.0}, {'speed': 10.0}, {'speed': 100.0}, {'speed': 1000.0}],
    'cradle': [{'n': 5}],
    'dimer_column': [{'n': 10}, {'n': 40}],
}
#: the quasi-static scenes (MD may damp; CD is swept over tolerances too)
REST_SCENES = ('column', 'mass_ratio', 'dimer_column')
CD_DT = {
    'incline': [2e-2, 1e-2, 1e-3, 1e-4, 1e-5],
    'column': [3e-2, 1e-2, 1e-3, 1e-4],
    'mass_ratio': [3e-2, 1e-2, 1e-3, 1e-4],
    'binary': [1e-2, 3e-3, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7],
    'projectile': [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7],
    'cradle': [1e-3, 3e-4, 1e-4, 1e-5, 1e-6],
    'dimer_column': [3e-2, 1e-2, 1e-3, 1e-4],
}
REST_TOL = [1e-2, 1e-4, 1e-6, 1e-8]
RELAX = 1.5   # the plugin's optional over-relaxation, tried on the rest scenes besides plain GS (1)


def md_variants(scene, case):
    """(law, damping, en) combinations a user would pick for this scene."""
    if scene in REST_SCENES:  # quasi-static: Cundall damping, or Hertz's contact damping
        return [('linear', d, None) for d in (0.2, 0.4, 0.7)] + [('hertz', d, 0.5) for d in (0.0, 0.4)]
    if scene == 'incline':
        return [('linear', 0.0, None), ('hertz', 0.0, 0.5)]
    if scene == 'binary' and case['en'] != 1.0:
        return [('hertz', 0.0, case['en'])]  # the linear law has no restitution below 1
    return [('linear', 0.0, None), ('hertz', 0.0, 1.0)]


def sim_time(scene, case):
    """Simulated time [s] a run of ``scene`` and ``case`` covers."""
    return {'incline': 0.2, 'column': {10: 0.5, 40: 0.5}.get(case.get('n'), 1.0), 'dimer_column': 0.5, 'mass_ratio': 1.0, 'binary': 0.02,
            'projectile': 0.7 / case.get('speed', 1.0), 'cradle': 0.03}[scene]


def md_steps(scene, case, young, safety):
    """MD steps a run needs at stiffness ``young`` and ``safety`` (its time step is
    safety·PWaveTimeStep of the lightest sphere)."""
    return sim_time(scene, case) / (safety * 0.01 * (1000.0 / young) ** 0.5)  # PWaveTimeStep of the lightest sphere


def plan(quick, only=None):
    """The list of runs (scene, case, method, settings): the short set with ``quick``, the full
    sweep otherwise; with ``only``, the runs of those scenes alone."""
    runs = []
    if quick:
        runs += [('incline', {'regime': 'rolling'}, 'CD', dict(dt=1e-3)),
                 ('incline', {'regime': 'rolling'}, 'MD', dict(young=1e7, safety=0.5)),
                 ('column', {'n': 10}, 'CD', dict(dt=1e-3, tolerance=1e-6)),
                 ('column', {'n': 10}, 'CD', dict(dt=1e-3, tolerance=1e-6, maxIter=20)),
                 ('column', {'n': 10}, 'MD', dict(young=1e7, safety=0.5, damping=0.4)),
                 ('column', {'n': 10}, 'MD', dict(young=1e7, safety=3.0, damping=0.4, group='stability')),
                 ('binary', {'en': 0.5}, 'CD', dict(dt=1e-4)),
                 ('binary', {'en': 0.5}, 'MD', dict(young=1e7, safety=0.5, law='hertz', en=0.5)),
                 ('projectile', {'speed': 100.0}, 'CD', dict(dt=1e-3)),
                 ('projectile', {'speed': 100.0}, 'MD', dict(young=1e6, safety=0.5)),
                 ('projectile', {'speed': 100.0}, 'MD', dict(young=1e9, safety=0.5))]
        return runs
    for scene, cases in CASES.items():
        for case in cases:
            rest = scene in REST_SCENES
            safeties = SAFETY_160 if case.get('n') == 160 else SAFETY
            for law, damping, en in md_variants(scene, case):
                grid = [(young, s) for young in YOUNG for s in safeties]
                if not rest:
                    grid += [(young, s) for young in YOUNG_STIFF for s in SAFETY_STIFF]
                elif scene == 'mass_ratio' and law == 'linear':
                    grid += [(1e10, s) for s in (2.0, 3.0)]
                for young, s in grid:
                    if md_steps(scene, case, young, s) <= MAX_STEPS:
                        runs.append((scene, case, 'MD', dict(young=young, safety=s, damping=damping, law=law, en=en,
                                                             group='stability' if s > 1 else 'accuracy')))
            dts = [dt for dt in CD_DT[scene] if not (case.get('n') == 160 and dt < 1e-3)
                   and sim_time(scene, case) / dt <= MAX_STEPS / 2]
            for dt in dts:
                for tol in (REST_TOL if rest else [1e-6]):
                    runs.append((scene, case, 'CD', dict(dt=dt, tolerance=tol)))
                    if rest and dt >= 1e-3:
                        runs.append((scene, case, 'CD', dict(dt=dt, tolerance=tol, relaxation=RELAX)))
            if rest:  # where the solver gives up: YADE-like default maxIter and a small one
                for mi in (1000, 100):
                    runs.append((scene, case, 'CD', dict(dt=1e-3, tolerance=1e-6, maxIter=mi, group='stability')))
    if only:
        runs = [r for r in runs if r[0] in only]
    return runs


FIELDS = ['scene', 'case', 'method', 'law', 'group', 'dt', 'young', 'safety', 'damping', 'en', 'tolerance',
          'maxIter', 'relaxation', 'schedule', 'status', 'error', 'force_error', 'vel_error', 'pos_error', 'restitution', 'overlap_max_rel',
          'overlap_mean_rel', 'overlap_final_rel', 'energy_drift', 'sim_time', 'steps', 'wall_s',
          'wall_per_sim_s', 'repeats', 'sweeps_total', 'sweeps_per_step', 'unconverged_steps', 't_settle_0.01',
          'wall_settle_0.01', 't_settle_0.001', 'wall_settle_0.001', 'cd_build', 'note']


def key(scene, case, method, p):
    """Identity of a run, from its parameters (plan) or from its CSV row."""
    g = lambda k: '%g' % float(p.get(k) or 0)  # noqa: E731
    if method == 'CD':
        return (scene, case, 'CD', g('dt'), g('tolerance'), g('maxIter'), '%g' % float(p.get('relaxation') or 1))
    return (scene, case, 'MD-' + p.get('law', 'linear').replace('MD-', ''), g('young'), g('safety'), g('damping'), g('en'))


def case_label(scene, case):
    """The short label of a case in the tables and the CSV (N=40, e=0.5, v=100...)."""
    return {'incline': lambda: case['regime'], 'column': lambda: 'N=%d' % case['n'], 'dimer_column': lambda: 'N=%d' % case['n'],
            'mass_ratio': lambda: 'ratio=%g' % case['ratio'], 'binary': lambda: 'e=%g' % case['en'],
            'projectile': lambda: 'v=%g' % case['speed'], 'cradle': lambda: 'n=%d' % case['n']}[scene]()


def cd_build():
    """Fingerprint of the loaded CD plugin (it may be reinstalled while a sweep runs: rows with
    different fingerprints are not comparable)."""
    from ..runs.runstate import plugin_digest
    return plugin_digest()[:10]


def run_all(csv_path, quick=False, scenes=None, resume=False, dry_run=False, momentum=False, max_wall=120.0):
    """Run every planned case (:func:`plan`) into the CSV ``csv_path``, appending rows as they
    come; with ``resume``, only the cases not yet in it. ``dry_run`` lists the runs only;
    ``momentum`` runs CD with the engine's momentum (the comparison's own protocol pins plain
    Gauss–Seidel); ``max_wall`` [s] stops any single run."""
    runs = plan(quick, scenes)
    rows = []
    done = set()
    if resume and os.path.exists(csv_path):
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        done = {key(r['scene'], r['case'], r['method'], r) for r in rows}
    os.makedirs(os.path.dirname(os.path.abspath(csv_path)), exist_ok=True)
    todo = []
    for scene, case, method, p in runs:
        p = dict(p)
        if method == 'CD':
            p.setdefault('tolerance', 1e-6)
            p.setdefault('maxIter', CD_MAXITER)
        else:
            p.setdefault('law', 'linear')
        if key(scene, case_label(scene, case), method, p) not in done:
            todo.append((scene, case, method, p))
    print('%d runs to do (%d kept)' % (len(todo), len(rows)))
    if dry_run:
        for t in todo:
            print(t)
        return rows
    write = open(csv_path, 'w', newline='')
    w = csv.DictWriter(write, fieldnames=FIELDS, extrasaction='ignore')
    w.writeheader()
    w.writerows(rows)
    write.flush()
    t_start = time.time()
    build0 = cd_build()
    print('CD plugin build', build0)
    for n, (scene, case, method, p) in enumerate(todo):
        p = dict(p)
        group = p.pop('group', 'accuracy')
        t0 = time.time()
        if method == 'CD' and momentum:
            p = dict(p, momentum=True)
        r = compare.run(scene, method, case, max_wall=max_wall, **p)
        r['group'] = group
        r['cd_build'] = build0 if method == 'CD' else ''
        if method == 'CD' and n % 20 == 0 and cd_build() != build0:
            print('WARNING: the CD plugin was reinstalled during the sweep: rerun with --resume after removing CD rows')
        rows.append(r)
        w.writerow(r)
        write.flush()
        print('[%4d/%d %6.0fs] %-10s %-10s %-9s %-48s %-8s err=%-9.3g ov=%-9.3g wall/sim=%-9.3g (%.1fs)' % (
            n + 1, len(todo), time.time() - t_start, scene, r['case'], r['law'],
            ' '.join('%s=%g' % (k, v) for k, v in p.items() if k != 'law' and v is not None), r['status'],
            r['error'], r['overlap_max_rel'], r['wall_per_sim_s'], time.time() - t0))
        sys.stdout.flush()
    write.close()
    print('saved', csv_path, '(%.0f s)' % (time.time() - t_start))
    return rows


# ----------------------------------------------------------------------------------------------
# analysis

def num(r, k):
    """The row's value ``k`` as a float, nan when it is missing or not a number."""
    try:
        v = float(r[k])
    except (KeyError, TypeError, ValueError):
        return float('nan')
    return v


FAIL = ('explodes', 'tunnels')
FLOOR = 1e-16


def pareto(points):
    """Lower-left front of (cost, error) points: sorted by cost, each improving the error."""
    front, best = [], float('inf')
    for c, e in sorted(points):
        if e < best:
            front.append((c, e))
            best = e
    return front


def strict_error(r):
    """The scene's error or the largest interpenetration/diameter seen during the run, whichever
    is larger: distance to the rigid-body solution including positions."""
    return max(num(r, 'error'), num(r, 'overlap_max_rel'))


def cheapest(rows, eps, err=lambda r: num(r, 'error')):
    # 'drifts' is allowed: it matters only when err is not the scene's own error (e.g. velocities only)
    """The row of ``rows`` with the least wall time per simulated second among those that ran
    (or only drifted) to an error ``err`` within ``eps``; None when none did."""
    ok = [r for r in rows if r['status'] in ('ok', 'drifts') and err(r) <= eps]
    return min(ok, key=lambda r: num(r, 'wall_per_sim_s')) if ok else None


EPS = (1e-2, 1e-3, 1e-4)


def describe(r):
    """The setting of a row in words (CD: time step, tolerance, and maxIter or ω when not the
    default; MD: law, stiffness, safety factor and damping)."""
    if r is None:
        return '—'
    if r['method'] == 'CD':
        return 'h=%g tol=%g' % (num(r, 'dt'), num(r, 'tolerance')) + (
            ' maxIter=%d' % num(r, 'maxIter') if num(r, 'maxIter') < CD_MAXITER else '') + (
            ' ω=%g' % num(r, 'relaxation') if num(r, 'relaxation') not in (1.0,) and num(r, 'relaxation') == num(r, 'relaxation') else '')
    s = '%s E=%g s=%g' % (r['law'].replace('MD-', ''), num(r, 'young'), num(r, 'safety'))
    if num(r, 'damping') > 0:
        s += ' d=%g' % num(r, 'damping')
    return s


def summary(rows):
    """Markdown tables: per case, the cheapest run of each method reaching each accuracy, the
    ratio MD/CD of their costs (> 1: CD cheaper), the same with interpenetration counted as an
    error, the time to accuracy of the rest scenes, and each method's failures."""
    order = [(sc, case_label(sc, c)) for sc, cs in CASES.items() for c in cs]
    cases = sorted({(r['scene'], r['case']) for r in rows},
                   key=lambda k: order.index(k) if k in order else len(order))
    lines = ['Cost at equal accuracy: cheapest run (wall time per simulated second) of each method whose '
             'error is ≤ ε and that did not fail (explode, tunnel, stall).', '']
    lines += equal_accuracy(rows, cases, lambda r: num(r, 'error'))
    dyn = [c for c in cases if c[0] in ('incline', 'binary', 'projectile', 'cradle')]
    lines += ['', 'Dynamic scenes, velocities only (the position part of the error left out): error = vel_error.', '']
    lines += equal_accuracy(rows, dyn, lambda r: num(r, 'vel_error'))
    lines += ['', 'The same as the first table, with the interpenetration counted: error = max(scene error, largest '
              'overlap/diameter during the run).', '']
    lines += equal_accuracy(rows, cases, strict_error)
    return '\n'.join(lines) + '\n' + summary_rest(rows, cases)


def equal_accuracy(rows, cases, err):
    """The equal-accuracy table (markdown lines): per scene, case and accuracy ε, the cheapest CD and
    MD runs by ``err`` and their cost ratio, and the same for CD without over-relaxation."""
    lines = ['| scene | case | accuracy ε | CD cost [s/s] (setting) | MD cost [s/s] (setting) | MD/CD | CD plain GS (ω=1) [s/s] | MD/CD(ω=1) |',
             '| --- | --- | --- | --- | --- | --- | --- | --- |']
    for scene, case in cases:
        rs = [r for r in rows if r['scene'] == scene and r['case'] == case]
        for eps in EPS:
            c = cheapest([r for r in rs if r['method'] == 'CD'], eps, err)
            c1 = cheapest([r for r in rs if r['method'] == 'CD' and not num(r, 'relaxation') > 1], eps, err)
            m = cheapest([r for r in rs if r['method'] == 'MD'], eps, err)
            cost = lambda r: num(r, 'wall_per_sim_s')  # noqa: E731
            lines.append('| %s | %s | %g | %s | %s | %s | %s | %s |' % (
                scene, case, eps, '%.3g (%s)' % (cost(c), describe(c)) if c else '— (none)',
                '%.3g (%s)' % (cost(m), describe(m)) if m else '— (none)',
                '%.3g' % (cost(m) / cost(c)) if c and m else '—',
                '%.3g' % cost(c1) if c1 else '—', '%.3g' % (cost(m) / cost(c1)) if c1 and m else '—'))
    return lines


def boundaries(rs, meth):
    """Where a method fails, in words: MD, per law, the smallest safety factor that explodes
    (and the largest that did not), the stiffest E that tunnels; CD, the settings that stall or
    drift."""
    out = []
    if meth == 'MD':
        for law in sorted({r['law'] for r in rs}):
            lr = [r for r in rs if r['law'] == law]
            ex = [num(r, 'safety') for r in lr if r['status'] == 'explodes']
            fine = [num(r, 'safety') for r in lr if r['status'] in ('ok', 'drifts')]
            tu = [r for r in lr if r['status'] == 'tunnels']
            parts = []
            if ex:
                parts.append('explodes from safety %g (none up to %g)' % (min(ex), max([f for f in fine if f < min(ex)] or [0])))
            if tu:
                parts.append('tunnels for E ≤ %g (%d runs)' % (max(num(r, 'young') for r in tu), len(tu)))
            dr = [r for r in lr if r['status'] == 'drifts']
            if dr:
                parts.append('%d drift' % len(dr))
            if parts:
                out.append('%s: %s' % (law.replace('MD-', ''), ', '.join(parts)))
    else:
        for st in ('stalls', 'drifts'):
            bad = [describe(r) for r in rs if r['status'] == st]
            if bad:
                out.append('%s: %s' % (st, '; '.join(bad)))
    return '; '.join(out)


def summary_rest(rows, cases):
    """The time-to-accuracy table of the rest scenes (markdown lines): per case and ε, the wall
    time until the floor-force error stays below ε, cheapest CD and MD runs."""
    lines = []
    rest = [(s_, c_) for s_, c_ in cases if s_ in REST_SCENES]
    if rest:
        lines += ['', 'Time to accuracy (rest scenes): wall time until the floor-force error stays below ε, among runs '
                  'whose final error (force and overlap) is ≤ ε.', '',
                  '| scene | case | ε | CD [s] (setting) | MD [s] (setting) | MD/CD |', '| --- | --- | --- | --- | --- | --- |']
        for scene, case in rest:
            rs = [r for r in rows if r['scene'] == scene and r['case'] == case and r['status'] == 'ok']
            for eps in (1e-2, 1e-3):
                best = {}
                for meth in ('CD', 'MD'):
                    ok = [r for r in rs if r['method'] == meth and num(r, 'error') <= eps
                          and math.isfinite(num(r, 'wall_settle_%g' % eps))]
                    best[meth] = min(ok, key=lambda r: num(r, 'wall_settle_%g' % eps)) if ok else None
                c, m = best['CD'], best['MD']
                w = lambda r: num(r, 'wall_settle_%g' % eps)  # noqa: E731
                lines.append('| %s | %s | %g | %s | %s | %s |' % (
                    scene, case, eps, '%.3g (%s)' % (w(c), describe(c)) if c else '—',
                    '%.3g (%s)' % (w(m), describe(m)) if m else '—', '%.3g' % (w(m) / w(c)) if c and m and w(c) > 0 else '—'))
    lines += ['', '| scene | case | method | runs | ok | drifts | stalls | tunnels | explodes | failure boundaries |',
              '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |']
    for scene, case in cases:
        for meth in ('CD', 'MD'):
            rs = [r for r in rows if r['scene'] == scene and r['case'] == case and r['method'] == meth]
            cnt = {s: sum(1 for r in rs if r['status'] == s) for s in compare.STATUSES}
            lines.append('| %s | %s | %s | %d | %d | %d | %d | %d | %d | %s |' % (
                scene, case, meth, len(rs), cnt['ok'], cnt['drifts'], cnt['stalls'], cnt['tunnels'], cnt['explodes'],
                boundaries(rs, meth)))
    return '\n'.join(lines) + '\n'


# ----------------------------------------------------------------------------------------------
# figures (matplotlib through the Agg canvas, no pyplot)

COLORS = {'CD': '#1f77b4', 'MD-linear': '#ff7f0e', 'MD-hertz': '#2ca02c'}
MARK = {'ok': 'o', 'drifts': 's', 'stalls': 'D', 'tunnels': 'v', 'explodes': 'X'}


def figures(rows, figs):
    """Two charts per scene into ``figs`` (cost against accuracy, and the failure map over the
    settings); returns the paths written."""
    from matplotlib.figure import Figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    os.makedirs(figs, exist_ok=True)
    written = []
    for scene in compare.SCENES:
        rs = [r for r in rows if r['scene'] == scene]
        if not rs:
            continue
        cases = []
        for r in rs:
            if r['case'] not in cases:
                cases.append(r['case'])
        # error against cost, with Pareto fronts
        fig = Figure(figsize=(max(8.0, 4.2 * len(cases)), 3.9))
        FigureCanvasAgg(fig)
        for j, case in enumerate(cases):
            ax = fig.add_subplot(1, len(cases), j + 1)
            cr = [r for r in rs if r['case'] == case]
            errs = [max(num(r, 'error'), FLOOR) for r in cr if math.isfinite(num(r, 'error'))]
            top = max(errs + [1.0]) * 10
            for law, col in COLORS.items():
                for st, mk in MARK.items():
                    pts = [(num(r, 'wall_per_sim_s'), max(num(r, 'error'), FLOOR) if math.isfinite(num(r, 'error')) else top)
                           for r in cr if r['law'] == law and r['status'] == st]
                    if pts:
                        ax.scatter([p[0] for p in pts], [p[1] for p in pts], c=col, marker=mk, s=22 if st == 'ok' else 34,
                                   alpha=0.75, edgecolors='none' if st == 'ok' else 'k', linewidths=0.5,
                                   label='%s %s' % (law, st) if j == 0 else None)
            for meth, col, ls in (('CD', COLORS['CD'], '-'), ('MD', '#d62728', '--')):
                front = pareto([(num(r, 'wall_per_sim_s'), max(num(r, 'error'), FLOOR)) for r in cr
                                if r['method'] == meth and r['status'] in ('ok', 'drifts')])
                if front:
                    xs, ys = [], []
                    for c, e in front:
                        if xs:
                            xs.append(c)
                            ys.append(ys[-1])
                        xs.append(c)
                        ys.append(e)
                    ax.plot(xs, ys, ls, color=col, lw=1.5, label=('%s Pareto front' % meth) if j == 0 else None)
            ax.set_xscale('log')
            ax.set_yscale('log')
            ax.axhline(top, color='0.6', lw=0.5)
            ax.set_title('%s %s' % (scene, case), fontsize=10)
            ax.set_xlabel('wall time per simulated second [s/s]')
            if j == 0:
                ax.set_ylabel('error (failed runs on the grey line)')
            ax.grid(True, which='major', lw=0.3)
        fig.legend(loc='lower center', ncol=6, fontsize=7, frameon=False)
        fig.tight_layout(rect=(0, 0.12, 1, 1))
        p = os.path.join(figs, 'compare_%s.png' % scene)
        fig.savefig(p, dpi=110)
        written.append(p)
        # stability: error against the time step (MD: safety factor; CD: h), MD overlap against E
        fig = Figure(figsize=(13, 3.2 * len(cases)))
        FigureCanvasAgg(fig)
        for j, case in enumerate(cases):
            cr = [r for r in rs if r['case'] == case]
            errs = [max(num(r, 'error'), FLOOR) for r in cr if math.isfinite(num(r, 'error'))]
            top = max(errs + [1.0]) * 10
            mr = [r for r in cr if r['method'] == 'MD']
            # MD: error vs safety factor, one line per (law, damping, E)
            ax = fig.add_subplot(len(cases), 3, 3 * j + 1)
            for g in sorted({(r['law'], num(r, 'damping'), num(r, 'young')) for r in mr}):
                gr = sorted([r for r in mr if (r['law'], num(r, 'damping'), num(r, 'young')) == g], key=lambda r: num(r, 'safety'))
                xs = [num(r, 'safety') for r in gr]
                ys = [max(num(r, 'error'), FLOOR) if math.isfinite(num(r, 'error')) else top for r in gr]
                ax.plot(xs, ys, '-', color=COLORS[g[0]], lw=0.5, alpha=0.5)
                for x, y, r in zip(xs, ys, gr):
                    ax.scatter([x], [y], c=COLORS[g[0]], marker=MARK[r['status']], s=20, alpha=0.8,
                               edgecolors='none' if r['status'] == 'ok' else 'k', linewidths=0.5)
            n = [r for r in mr if r['status'] == 'explodes']
            if n:  # tunnelling depends on E and speed, not on the step: no line for it
                s_min = min(num(r, 'safety') for r in n)
                ax.axvline(s_min, color='r', ls=':', lw=0.8)
                ax.text(s_min, top, ' explodes from %g' % s_min, fontsize=7, va='top', rotation=90)
            for law in sorted({r['law'] for r in mr}):
                ax.plot([], [], '-', color=COLORS[law], label=law)
            ax.legend(fontsize=6, frameon=False, loc='lower right')
            ax.set_xlabel('MD: O.dt / PWaveTimeStep()')
            ax.set_ylabel('error')
            # MD: largest overlap vs Young's modulus (tunnelling is a stiffness/speed matter)
            ax2 = fig.add_subplot(len(cases), 3, 3 * j + 2)
            for r in mr:
                ov = num(r, 'overlap_max_rel')
                ax2.scatter([num(r, 'young') * (1 + 0.15 * (num(r, 'safety') - 1) / 4)], [max(ov, 1e-9)], c=COLORS[r['law']],
                            marker=MARK[r['status']], s=18, alpha=0.7, edgecolors='none' if r['status'] == 'ok' else 'k', linewidths=0.5)
            ax2.axhline(1.0, color='m', ls=':', lw=0.8)
            ax2.set_xscale('log')
            ax2.set_yscale('log')
            ax2.set_xlabel("MD: Young's modulus E [Pa] (jittered by safety)")
            ax2.set_ylabel('largest overlap / diameter')
            ax2.set_title('%s %s — MD interpenetration' % (scene, case), fontsize=7)
            ax2.grid(True, lw=0.3)
            # CD: error vs h, one line per (tolerance, maxIter, relaxation)
            ax3 = fig.add_subplot(len(cases), 3, 3 * j + 3)
            cdr = [r for r in cr if r['method'] == 'CD']
            for tol, mi, om in sorted({(num(r, 'tolerance'), num(r, 'maxIter'), num(r, 'relaxation')) for r in cdr}):
                gr = sorted([r for r in cdr if (num(r, 'tolerance'), num(r, 'maxIter'), num(r, 'relaxation')) == (tol, mi, om)],
                            key=lambda r: num(r, 'dt'))
                xs = [num(r, 'dt') for r in gr]
                ys = [max(num(r, 'error'), FLOOR) if math.isfinite(num(r, 'error')) else top for r in gr]
                ax3.plot(xs, ys, '-' if om == 1 else '--', lw=0.6, alpha=0.7,
                         label='tol %g%s%s' % (tol, '' if mi >= CD_MAXITER else ' maxIter %d' % mi, '' if om == 1 else ' ω=%g' % om))
                for x, y, r in zip(xs, ys, gr):
                    ax3.scatter([x], [y], c=COLORS['CD'], marker=MARK[r['status']], s=22,
                                edgecolors='none' if r['status'] == 'ok' else 'k', linewidths=0.5)
            ax3.set_xlabel('CD: time step h [s]')
            ax3.legend(fontsize=5.5, frameon=False)
            for a_, meth in ((ax, 'MD'), (ax3, 'CD')):
                a_.set_xscale('log')
                a_.set_yscale('log')
                a_.axhline(top, color='0.6', lw=0.5)
                a_.set_ylabel('error')
                a_.set_title('%s %s — %s (markers: %s)' % (scene, case, meth, ', '.join('%s %s' % (m, s) for s, m in MARK.items())),
                             fontsize=7)
                a_.grid(True, lw=0.3)
        fig.tight_layout()
        p = os.path.join(figs, 'compare_%s_stability.png' % scene)
        fig.savefig(p, dpi=100)
        written.append(p)
    return written


def sweep(csv_path, figs, plot_only=False, dry_run=False, **run_options):
    """Run the sweep (:func:`run_all` with ``run_options``), or with ``plot_only`` reload it from
    ``csv_path``, then write its summary next to the CSV and its charts into ``figs``."""
    if plot_only:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
    else:
        rows = [{k: ('' if v is None else v) for k, v in r.items()} for r in run_all(csv_path, dry_run=dry_run, **run_options)]
        rows = [{k: str(v) for k, v in r.items()} for r in rows]
    if not dry_run and rows:
        s = summary(rows)
        out = os.path.splitext(csv_path)[0] + '_summary.md'
        with open(out, 'w') as f:
            f.write(s)
        print(s)
        print('saved', out)
        for p in figures(rows, figs):
            print('saved', p)
    return rows
