"""Statistics the pile analyses share: robust straight-line fits (bisquare, Theil–Sen, Huber),
small-sample Student-t intervals and quantiles, the jackknife of a ratio, the first crossing of a
series, and the trend of a pile observable with size (a line through single piles, with pooled
and Welch intervals, and the interval a new pile may fall in).
"""

import math
import numpy as np


def linear_fit(x, y):
    """Least-squares line y = a + b·x. Returns (a, b, standard error of b); the error is nan
    with fewer than 3 points."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if len(x) < 2:
        return float('nan'), float('nan'), float('nan')
    xm, ym = x.mean(), y.mean()
    sxx = ((x - xm) ** 2).sum()
    if sxx == 0:
        return float('nan'), float('nan'), float('nan')
    b = ((x - xm) * (y - ym)).sum() / sxx
    a = ym - b * xm
    if len(x) < 3:
        return float(a), float(b), float('nan')
    resid = y - a - b * x
    se_b = math.sqrt((resid ** 2).sum() / (len(x) - 2) / sxx)
    return float(a), float(b), se_b


def _weighted_line(x, y, w):
    """Weighted least-squares line y = a + b·x; (nan, nan) when degenerate."""
    sw = w.sum()
    if sw <= 0:
        return float('nan'), float('nan')
    xm, ym = (w * x).sum() / sw, (w * y).sum() / sw
    sxx = (w * (x - xm) ** 2).sum()
    if sxx <= 0:
        return float('nan'), float('nan')
    b = (w * (x - xm) * (y - ym)).sum() / sxx
    return float(ym - b * xm), float(b)


def _theil_sen(x, y):
    """Theil–Sen line: b = median of the pairwise slopes (distinct x), a = median(y - b·x)."""
    i, j = np.triu_indices(len(x), 1)
    dx = x[j] - x[i]
    ok = dx != 0
    if not ok.any():
        return float('nan'), float('nan')
    b = float(np.median((y[j] - y[i])[ok] / dx[ok]))
    return float(np.median(y - b * x)), b


def _bisquare_weights(e, c, s_floor):
    """Tukey's bisquare weights (1 - u²)² for |u| < 1, else 0, of the residuals ``e``, with
    u = e/(c·s) and s = max(1.4826·MAD(e), ``s_floor``)."""
    s = max(1.4826 * float(np.median(np.abs(e - np.median(e)))), s_floor)
    u = e / (c * s)
    return np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)


def robust_line(x, y, bin_width, c=4.685, max_iter=50, start=None):
    """Line y = a + b·x resistant to outliers (stray grains, a foot, a cap left in the window).

    Start: the Theil–Sen line through the medians of y in bins of x of width ``bin_width`` (or
    ``start`` = (a, b)), refined by 10 Huber iterations (weights min(1, 1.345 s/|residual|),
    never zero). Then Tukey's bisquare, iteratively reweighted: weights
    (1 - u²)² for |u| < 1, u = residual/(c·s), s = 1.4826·MAD of the residuals (floored at
    1e-9·ptp(y)); points farther than c·s get no weight. Returns (a, b, weights), (a, b) being
    the weighted least-squares line of those weights; (nan, nan, zeros) with fewer than two
    distinct bins, or fewer than two points (or, given ``start``, when no line is defined: all x
    equal).

    Degenerate case: exact data. s is the MAD about the median residual, the weights use the
    residual about the line. When more than half of the points lie exactly on a line (grains
    placed on a constructed cone, with outliers such as exposed buried grains), s collapses to
    round-off while the Huber line can still miss those points by more than c·s (a Huber
    weight moves the line by at most 1.345 s per point, so the pull shrinks with s and a start
    offset is not closed): the bisquare would give every point zero weight. So whenever a
    bisquare step would keep fewer than half of the points, the line is first moved by the
    median residual (a += median(e)); then at least half of the residuals lie within one MAD
    of 0 and keep a weight, and the iteration goes on: on points exactly on y = a0 + b0·x plus
    a gross outlier, or plus a parallel layer one grain lower, it ends on (a0, b0) to round-off
    (outliers so many and so near that the MAD spans them still give a compromise line, the
    bisquare's ordinary breakdown, not this case). With any scatter this cannot
    happen near the fit (it needs |median(e)| > (c·1.4826 - 1)·MAD ≈ 5.9 MAD), so ordinary
    data give the same numbers as before. Should the bisquare still define no line (every kept
    point at one x), the Huber line and its weights (never zero) are returned: the weights
    returned with a finite line are never all zero."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    w = np.zeros(len(x))
    if len(x) < 2:
        return float('nan'), float('nan'), w
    if start is None:
        k = np.floor(x / bin_width).astype(np.int64)
        cells = np.unique(k)
        if len(cells) < 2:
            return float('nan'), float('nan'), w
        xb = np.array([np.median(x[k == c_]) for c_ in cells])
        yb = np.array([np.median(y[k == c_]) for c_ in cells])
        a, b = _theil_sen(xb, yb)
    else:
        a, b = start
    if not np.isfinite(b):
        return float('nan'), float('nan'), w
    s_floor = 1e-9 * max(float(np.ptp(y)), 1e-300)   # exact data: the scale never reaches 0
    for _ in range(10):      # Huber first: never a zero weight, so a rough start cannot lose every point
        e = y - a - b * x
        s = max(1.4826 * float(np.median(np.abs(e - np.median(e)))), s_floor)
        w = np.minimum(1.0, 1.345 * s / np.maximum(np.abs(e), 1e-300))
        a, b = _weighted_line(x, y, w)
    if not (np.isfinite(a) and np.isfinite(b)):
        return float('nan'), float('nan'), np.zeros(len(x))
    fit = (float(a), float(b), w)       # the Huber line: what is returned if the bisquare defines none
    for _ in range(max_iter):
        e = y - a - b * x
        w = _bisquare_weights(e, c, s_floor)
        if 2 * np.count_nonzero(w) < len(x):     # the line misses the bulk (exact data): move it onto it
            a = a + float(np.median(e))
            w = _bisquare_weights(y - a - b * x, c, s_floor)
        a2, b2 = _weighted_line(x, y, w)
        if not np.isfinite(b2):
            break
        done = abs(b2 - b) <= 1e-12 * max(1.0, abs(b)) and abs(a2 - a) <= 1e-12 * max(1.0, abs(a))
        a, b = a2, b2
        fit = (float(a), float(b), w)
        if done:
            break
    return fit


_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
         2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
         2.052, 2.048, 2.045, 2.042)


def t_quantile_975(df):
    """0.975 quantile of Student's t with ``df`` degrees of freedom (table to 30, then the
    normal's 1.960 corrected by 2.4/df, within 0.002 of the exact value)."""
    df = int(df)
    if df < 1:
        return float('nan')
    return _T975[df - 1] if df <= 30 else 1.960 + 2.4 / df


def t_cdf(t, df):
    """Cumulative distribution of Student's t (``df`` > 0) at ``t``, by Simpson's rule on the
    density from 0 to |t| (2000 panels: error below 1e-9 for |t| < 50)."""
    if not math.isfinite(t):
        return 0.0 if t < 0 else 1.0
    x = np.linspace(0.0, min(abs(t), 1e3), 4001)
    logc = math.lgamma((df + 1) / 2) - math.lgamma(df / 2) - 0.5 * math.log(df * math.pi)
    f = np.exp(logc - (df + 1) / 2 * np.log1p(x * x / df))
    h = x[1] - x[0]
    half = h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
    return 0.5 + half if t >= 0 else 0.5 - half


def mean_interval(values):
    """Mean of the finite ``values``, their standard deviation (ddof 1), the standard error and
    the 95 % Student-t interval. Returns a dict (nan entries with fewer than two values)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    nan = float('nan')
    if len(v) == 0:
        return {'n': 0, 'mean': nan, 'std': nan, 'sem': nan, 'ci95': (nan, nan)}
    m = float(v.mean())
    if len(v) < 2:
        return {'n': 1, 'mean': m, 'std': nan, 'sem': nan, 'ci95': (nan, nan)}
    sd = float(v.std(ddof=1))
    se = sd / math.sqrt(len(v))
    q = t_quantile_975(len(v) - 1)
    return {'n': int(len(v)), 'mean': m, 'std': sd, 'sem': se, 'ci95': (m - q * se, m + q * se)}


def batch_means(series, n_batches=10):
    """Mean of a correlated stationary time series (a steady shear's stress samples) with its
    standard error by non-overlapping batch means: the series is cut into ``n_batches`` equal
    consecutive batches (the first len % n_batches samples dropped), whose means are treated as
    independent (valid once a batch is much longer than the correlation time). Also the drift
    check: the difference of the second and first halves' means in units of its standard error
    (|z| > 3 says the series is not yet steady). Returns a dict: n (samples used), mean, sem,
    ci95 (Student t with n_batches − 1 degrees of freedom), batches, drift_z; nan entries with
    fewer than two samples per batch."""
    x = np.asarray([v for v in series if v is not None and math.isfinite(v)], dtype=float)
    nan = float('nan')
    k = int(n_batches)
    if k < 2:
        raise ValueError('batch_means needs n_batches >= 2, not %r' % (n_batches,))
    size = len(x) // k
    if size < 2:
        return {'n': int(len(x)), 'mean': float(x.mean()) if len(x) else nan, 'sem': nan, 'ci95': (nan, nan),
                'batches': k, 'drift_z': nan}
    x = x[len(x) - k * size:]
    return _batch_summary(x.reshape(k, size).mean(axis=1), len(x))


def _batch_summary(means, n):
    """Mean, standard error, 95 % interval and drift z of independent batch values ``means``."""
    k = len(means)
    m = float(means.mean())
    se = float(means.std(ddof=1) / math.sqrt(k))
    q = t_quantile_975(k - 1)
    h = k // 2
    first, second = means[:h], means[h:2 * h]
    se_d = math.sqrt(first.var(ddof=1) / h + second.var(ddof=1) / h) if h >= 2 else float('nan')
    drift = float((second.mean() - first.mean()) / se_d) if se_d and math.isfinite(se_d) and se_d > 0 else float('nan')
    return {'n': int(n), 'mean': m, 'sem': se, 'ci95': (m - q * se, m + q * se), 'batches': k, 'drift_z': drift}


def batch_ratio(num, den, n_batches=10):
    """The ratio of the means of two paired stationary series (μ = τ/p from stress samples whose
    denominator fluctuates), with its error by batch means: the ratio of each batch's means, then
    their mean, standard error and interval as :func:`batch_means` gives them (so the error
    carries the correlation of numerator and denominator). Unlike the mean of the per-sample
    ratios, it is not biased by a fluctuating denominator. Returns the same dict as
    :func:`batch_means` (``n``: samples used)."""
    pairs = [(a, b) for a, b in zip(num, den) if a is not None and b is not None and math.isfinite(a) and math.isfinite(b)]
    k = int(n_batches)
    size = len(pairs) // max(k, 1)
    if k < 2 or size < 1:
        return batch_means([a / b for a, b in pairs if b != 0], max(k, 2))
    means = np.array(pairs[len(pairs) - k * size:], dtype=float).reshape(k, size, 2).mean(axis=1)
    return _batch_summary(means[:, 0] / means[:, 1], k * size)


def jackknife_ratio_dip(num, den, w_num=1.0, w_den=1.0):
    """D = 1 - (w_num·sum num)/(w_den·sum den) over groups (sectors or piles), with its
    delete-one jackknife standard error, the 95 % Student-t interval (groups - 1 degrees of
    freedom) and the one-sided confidence that D > 0 from the t statistic D/se.

    :param num, den: per-group totals (the central and the reference loads).
    :returns: dict ``D``, ``se``, ``ci95``, ``confidence_positive``, ``groups``."""
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    k = len(num)
    nan = float('nan')
    if k == 0 or den.sum() <= 0:
        return {'D': nan, 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    D = 1 - (w_num * num.sum()) / (w_den * den.sum())
    if k < 2:
        return {'D': float(D), 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    den_minus = den.sum() - den
    with np.errstate(divide='ignore', invalid='ignore'):
        loo = 1 - (w_num * (num.sum() - num)) / (w_den * den_minus)
    loo = loo[np.isfinite(loo)]
    if len(loo) < 2:
        return {'D': float(D), 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    se = math.sqrt((len(loo) - 1) / len(loo) * ((loo - loo.mean()) ** 2).sum())
    q = t_quantile_975(k - 1)
    conf = t_cdf(D / se, k - 1) if se > 0 else (1.0 if D > 0 else 0.0)
    return {'D': float(D), 'se': se, 'ci95': (D - q * se, D + q * se), 'confidence_positive': conf,
            'groups': k}


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


def t_quantile(p, df):
    """The ``p`` quantile (0 < p < 1) of Student's t with ``df`` > 0 degrees of freedom, any real
    df (a Welch–Satterthwaite count), by bisection on :func:`t_cdf` to 1e-10."""
    if not (0 < p < 1) or not df > 0:
        raise ValueError('t_quantile: need 0 < p < 1 and df > 0 (got p=%r, df=%r)' % (p, df))
    if p < 0.5:
        return -t_quantile(1 - p, df)
    lo, hi = 0.0, 1.0
    while t_cdf(hi, df) < p:
        lo, hi = hi, 2 * hi
    while hi - lo > 1e-10 * max(1.0, hi):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if t_cdf(mid, df) < p else (lo, mid)
    return 0.5 * (lo + hi)


def _welch_slope(x, y, groups):
    """Least-squares slope of y on x where x is constant within each group, with the variance of
    that slope from each group's own scatter (a linear contrast of the group means) and its
    Welch–Satterthwaite degrees of freedom. Every group needs two values or more."""
    xb = x.mean()
    sxx = ((x - xb) ** 2).sum()
    b = ((x - xb) * (y - y.mean())).sum() / sxx
    parts = []
    for g in groups:
        m = g.sum()
        c = m * (x[g][0] - xb) / sxx          # the slope is sum over groups of c * (group mean)
        parts.append((c * c * y[g].var(ddof=1) / m, m - 1))
    var = sum(v for v, _ in parts)
    den = sum(v * v / d for v, d in parts)
    return float(b), math.sqrt(var), (var * var / den if den > 0 else float('inf'))


def size_trend(n_grains, values):
    """Does an observable of single piles change with the pile's size? The least-squares line
    of ``values`` (one per pile: D, a slope...) against log10 of the grain count: its slope per
    decade of grains, with two 95 % intervals and the one-sided confidence that it is positive.

    * ``*_t``: Student's t on the ordinary least-squares slope over every pile (n - 2 degrees
      of freedom): exact when the piles' scatter is normal and the same at every size; a size
      with a single pile (the full pile) takes part with the pooled scatter;
    * ``*_welch``: the same slope over the sizes with two piles or more, its variance from each
      size's own scatter (the slope is a linear contrast of the sizes' means) with
      Welch–Satterthwaite's degrees of freedom: right when the scatter changes with the size,
      which the pooled t is not (tested by coverage on constructed ensembles).

    Piles whose value is not finite are left out; fewer than two sizes give nan.

    :returns: dict ``slope``, ``intercept``, ``se``, ``ci95_t``, ``confidence_t`` (all piles);
        ``slope_welch``, ``se_welch``, ``df_welch``, ``ci95_welch``, ``confidence_welch``
        (replicated sizes); ``n_piles``, ``sizes`` (N -> piles), ``single_sizes``.
    """
    n = np.asarray(n_grains, dtype=float)
    y = np.asarray(values, dtype=float)
    if n.shape != y.shape:
        raise ValueError('size_trend: %d grain counts for %d values' % (n.size, y.size))
    ok = np.isfinite(y) & np.isfinite(n)
    if np.any(n[ok] <= 0):
        raise ValueError('size_trend: grain counts must be positive (got %r)' % (sorted(set(n[ok][n[ok] <= 0])),))
    n, y = n[ok], y[ok]
    x = np.log10(n)
    sizes = {int(k): int((n == k).sum()) for k in sorted(set(n))}
    nan = float('nan')
    out = {'slope': nan, 'intercept': nan, 'se': nan, 'ci95_t': (nan, nan), 'confidence_t': nan,
           'slope_welch': nan, 'se_welch': nan, 'df_welch': nan, 'ci95_welch': (nan, nan),
           'confidence_welch': nan, 'n_piles': int(len(y)), 'sizes': sizes,
           'single_sizes': [k for k, c in sizes.items() if c == 1]}
    if len(sizes) < 2:
        return out

    def conf(b, se, df):
        return t_cdf(b / se, df) if se > 0 else (1.0 if b > 0 else 0.0 if b < 0 else 0.5)

    a, b, se = linear_fit(x, y)
    out.update(slope=b, intercept=a, se=se)
    if math.isfinite(se):
        q = t_quantile(0.975, len(y) - 2)
        out.update(ci95_t=(b - q * se, b + q * se), confidence_t=conf(b, se, len(y) - 2))
    rep = [k for k, c in sizes.items() if c >= 2]
    if len(rep) >= 2:
        keep = np.isin(n, rep)
        bw, sw, df = _welch_slope(x[keep], y[keep], [n[keep] == k for k in rep])
        q = t_quantile(0.975, df) if sw > 0 else 0.0
        out.update(slope_welch=bw, se_welch=sw, df_welch=df, ci95_welch=(bw - q * sw, bw + q * sw),
                   confidence_welch=conf(bw, sw, df))
    return out


def line_prediction(x, y, x0, m=1):
    """Where the least-squares line of ``y`` on ``x`` puts new values at ``x0``, and how far the
    mean of ``m`` new values (independent, the line's scatter each) may fall from it: the 95 %
    prediction interval (Student's t, n − 2 degrees of freedom; s·√(1/m + 1/n + (x0 − x̄)²/Sxx),
    the line's own uncertainty at x0 included, which grows away from the data: an extrapolation is
    wider than the scatter alone). ``m = 1`` is one new value.

    :returns: dict ``value``, ``se`` (of the mean of m new values), ``ci95``, ``df``, ``m``; nan
        with fewer than 3 points or a single distinct x.
    :raises ValueError: when ``m`` is not a positive integer."""
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
        raise ValueError('line_prediction: m (new values averaged) must be a positive integer, got %r' % (m,))
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    nan = float('nan')
    out = {'value': nan, 'se': nan, 'ci95': (nan, nan), 'df': len(x) - 2, 'm': int(m)}
    a, b, se_b = linear_fit(x, y)
    if not math.isfinite(se_b):
        return out
    n = len(x)
    s = math.sqrt(((y - a - b * x) ** 2).sum() / (n - 2))
    sxx = ((x - x.mean()) ** 2).sum()
    value = a + b * x0
    se = s * math.sqrt(1 / m + 1 / n + (x0 - x.mean()) ** 2 / sxx)
    q = t_quantile(0.975, n - 2)
    return {'value': float(value), 'se': se, 'ci95': (value - q * se, value + q * se), 'df': n - 2, 'm': int(m)}
