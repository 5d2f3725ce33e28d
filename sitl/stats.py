"""Spread of the test metrics (issue 21, "honest statistics"): every number of Table 1 and of the
study is a mean over test windows (20-step rollouts from 22-frame windows of every seed); its
spread is a percentile bootstrap over those windows, and a comparison of two models evaluated on
the same windows is a paired bootstrap of the ratio of their means (the same resampled windows in
numerator and denominator, so that a window hard for both does not count as a difference).

Windows are not independent samples of the flow (consecutive windows of one trajectory are
correlated), so these intervals are a lower bound of the spread; a second training seed (the study's
`train_seeds`) shows the spread between trainings, which the windows cannot.
"""
import math

import numpy as np

LEVEL = 0.95


def _finite(values) -> np.ndarray:
    v = np.asarray(values, np.float64)
    if v.ndim != 1 or len(v) == 0:
        raise ValueError(f"stats: expected a non-empty 1-D list of per-window values, got shape {v.shape}")
    return v


def _resample(n: int, n_boot: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, n, size=(n_boot, n))


def bootstrap_ci(values, n_boot: int = 2000, level: float = LEVEL, seed: int = 0) -> tuple:
    """(lo, hi): the percentile bootstrap interval of the mean of `values` (one per window). NaN when
    any window is not finite (a diverged rollout: its mean is not finite either) and when there is
    one window (no spread can be estimated from one)."""
    v = _finite(values)
    if not np.all(np.isfinite(v)):
        return (math.nan, math.nan)
    if len(v) == 1:  # no spread can be estimated from one window
        return (math.nan, math.nan)
    means = v[_resample(len(v), n_boot, seed)].mean(axis=1)
    a = (1.0 - level) / 2
    return (float(np.quantile(means, a)), float(np.quantile(means, 1.0 - a)))


def _interval(samples, level: float) -> tuple:
    """(lo, hi): the central `level` percentile interval of bootstrap samples."""
    lo, hi = (1.0 - level) / 2, 1.0 - (1.0 - level) / 2
    return float(np.quantile(samples, lo)), float(np.quantile(samples, hi))


def paired_ratio(a, b, n_boot: int = 2000, level: float = LEVEL, seed: int = 0) -> tuple:
    """(mean(a) / mean(b), lo, hi) with the paired bootstrap interval of the ratio: a and b are the
    per-window values of two models on the same windows, in the same order. NaN when either has a
    non-finite window; the interval NaN for one window."""
    va, vb = _finite(a), _finite(b)
    if va.shape != vb.shape:
        raise ValueError(f"stats: paired values of different lengths {len(va)} and {len(vb)}")
    if not (np.all(np.isfinite(va)) and np.all(np.isfinite(vb))) or vb.mean() <= 0:
        return (math.nan, math.nan, math.nan)
    ratio = float(va.mean() / vb.mean())
    if len(va) == 1:
        return (ratio, math.nan, math.nan)
    idx = _resample(len(va), n_boot, seed)
    return (ratio, *_interval(va[idx].mean(axis=1) / vb[idx].mean(axis=1), level))


def unpaired_ratio(a, b, n_boot: int = 2000, level: float = LEVEL, seed: int = 0) -> tuple:
    """(mean(a) / mean(b), lo, hi) with the bootstrap interval of the ratio when a and b are the
    per-window values of two models on different windows (each resampled on its own): wider than the
    paired interval, which needs the same windows. NaN as `paired_ratio`."""
    va, vb = _finite(a), _finite(b)
    if not (np.all(np.isfinite(va)) and np.all(np.isfinite(vb))) or vb.mean() <= 0:
        return (math.nan, math.nan, math.nan)
    ratio = float(va.mean() / vb.mean())
    if min(len(va), len(vb)) == 1:
        return (ratio, math.nan, math.nan)
    r = va[_resample(len(va), n_boot, seed)].mean(axis=1) / vb[_resample(len(vb), n_boot, seed + 1)].mean(axis=1)
    return (ratio, *_interval(r, level))


MIN_WINDOWS = 10
"""Fewer windows than this never decide a comparison (a bootstrap over 2 windows is no interval)."""


EQUIVALENCE_MARGIN = 0.01
"""Two models are "equal" when the paired interval of their ratio lies inside 1 +- this margin: a
difference that small is below what separates two training seeds (the cpu study: 0.04 %) only by
luck, and is no difference a reader should act on."""

EQUAL = f"equal within +-{EQUIVALENCE_MARGIN:.0%}"


def verdict(lo: float, hi: float, n: int = MIN_WINDOWS, margin: float = EQUIVALENCE_MARGIN) -> str:
    """A ratio interval from n windows: EQUAL when it lies inside [1 - margin, 1 + margin] (checked
    first: a ratio of 1.0002 [1.0001, 1.0003] is equal, not higher), else 'lower' or 'higher' when
    it excludes 1, else 'undecided' (it contains 1 but reaches beyond the margin, is NaN, or rests
    on fewer than MIN_WINDOWS windows)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or n < MIN_WINDOWS:
        return "undecided"
    if 1.0 - margin <= lo and hi <= 1.0 + margin:
        return EQUAL
    return "lower" if hi < 1.0 else "higher" if lo > 1.0 else "undecided"
