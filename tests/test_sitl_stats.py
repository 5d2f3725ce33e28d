"""sitl/stats.py: the bootstrap interval of a mean over windows covers the true mean about as often
as it claims (normal samples, known mean), the paired ratio interval finds a known ratio and is
narrower than the unpaired intervals when the windows' difficulty is shared, and no verdict rests on
fewer than MIN_WINDOWS windows or on a diverged (non-finite) window."""
import math

import numpy as np

from sitl import stats


def test_bootstrap_interval_covers_the_mean_at_its_level():
    rng = np.random.default_rng(1)
    hits = 0
    for k in range(200):
        v = rng.normal(3.0, 1.0, 40)
        lo, hi = stats.bootstrap_ci(v, n_boot=500, seed=k)
        hits += lo <= 3.0 <= hi
    assert 0.86 <= hits / 200 <= 0.99, hits          # 95 % nominal; the percentile bootstrap is a bit narrow


def test_paired_ratio_of_shared_difficulty():
    rng = np.random.default_rng(2)
    hard = rng.lognormal(0.0, 1.0, 50)                 # per-window difficulty, shared by both models
    a = 0.8 * hard * rng.lognormal(0.0, 0.05, 50)
    b = hard
    r, lo, hi = stats.paired_ratio(a, b, n_boot=1000)
    assert lo < 0.8 < hi and hi < 1.0 and stats.verdict(lo, hi, 50) == "lower"
    # unpaired, the two means' intervals overlap: difficulty hides the difference
    la, ha = stats.bootstrap_ci(a)
    lb, hb = stats.bootstrap_ci(b)
    assert ha > lb
    assert stats.verdict(1 / hi, 1 / lo, 50) == "higher"


def test_no_verdict_from_few_or_diverged_windows():
    assert stats.verdict(0.5, 0.6, stats.MIN_WINDOWS - 1) == "undecided"
    assert stats.verdict(0.9, 1.1, 100) == "undecided"
    assert all(math.isnan(x) for x in stats.bootstrap_ci([1.0, math.inf, 2.0]))
    assert all(math.isnan(x) for x in stats.bootstrap_ci([1.0]))
    r, lo, hi = stats.paired_ratio([1.0, 2.0], [1.0, math.nan])
    assert math.isnan(r) and stats.verdict(lo, hi, 100) == "undecided"
