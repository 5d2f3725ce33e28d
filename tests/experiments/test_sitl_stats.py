"""sitl/stats.py: the bootstrap interval of a mean over windows covers the true mean about as often
as it claims (normal samples, known mean), the paired ratio interval finds a known ratio and is
narrower than the unpaired intervals when the windows' difficulty is shared, and no verdict rests on
fewer than MIN_WINDOWS windows or on a diverged (non-finite) window; a ratio prints with enough
digits to tell it from its interval (sitl/fmt.py)."""
import math

import numpy as np
import pytest

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


def test_unpaired_ratio_covers_a_known_ratio_and_is_wider_than_the_paired_one():
    """A GNS with a longer input history is tested on other windows than the solver alone: its ratio
    is resampled unpaired. Known ratio 0.8 of the means, different numbers of windows: the interval
    covers it in about 95 % of draws, and is wider than the paired interval of the same data."""
    rng = np.random.default_rng(4)
    hits = 0
    for k in range(100):
        a = 0.8 * rng.lognormal(0.0, 0.5, 40) / np.exp(0.125)   # mean 0.8 (lognormal mean exp(s^2/2))
        b = rng.lognormal(0.0, 0.5, 30) / np.exp(0.125)         # mean 1
        r, lo, hi = stats.unpaired_ratio(a, b, n_boot=500, seed=k)
        hits += lo <= 0.8 <= hi
    assert 0.85 <= hits / 100 <= 1.0, hits
    hard = rng.lognormal(0.0, 1.0, 50)
    a, b = 0.8 * hard * rng.lognormal(0.0, 0.05, 50), hard
    _, plo, phi = stats.paired_ratio(a, b, n_boot=1000)
    _, ulo, uhi = stats.unpaired_ratio(a, b, n_boot=1000)
    assert uhi - ulo > 3 * (phi - plo)
    assert all(math.isnan(x) for x in stats.unpaired_ratio([1.0, math.nan], [1.0, 2.0, 3.0]))


def test_an_interval_inside_the_equivalence_margin_is_equal_not_higher():
    """The cpu study's SitL against the solver alone: 1.0002 [1.0001, 1.0003] is a difference of
    0.02 %, below the +-1 % margin: equal, though the interval excludes 1; an interval reaching past
    the margin on one side only keeps its direction."""
    assert stats.verdict(1.0001, 1.0003, 50) == stats.EQUAL == "equal within +-1%"
    assert stats.verdict(0.995, 1.004, 50) == stats.EQUAL
    assert stats.verdict(1.001, 1.02, 50) == "higher" and stats.verdict(0.98, 0.999, 50) == "lower"
    assert stats.verdict(0.98, 1.02, 50) == "undecided"


def test_no_verdict_from_few_or_diverged_windows():
    assert stats.verdict(0.5, 0.6, stats.MIN_WINDOWS - 1) == "undecided"
    assert stats.verdict(0.9, 1.1, 100) == "undecided"
    assert all(math.isnan(x) for x in stats.bootstrap_ci([1.0, math.inf, 2.0]))
    assert all(math.isnan(x) for x in stats.bootstrap_ci([1.0]))
    r, lo, hi = stats.paired_ratio([1.0, 2.0], [1.0, math.nan])
    assert math.isnan(r) and stats.verdict(lo, hi, 100) == "undecided"


def test_a_ratio_prints_with_the_digits_that_tell_it_from_its_interval():
    """sitl.fmt.ratio_digits: three significant digits when they suffice; more when the interval's
    ends would print as the ratio itself (a "higher" verdict beside "1 [1, 1]") or a value other than
    1 as "1"; never more than six."""
    from sitl.fmt import ratio_digits

    assert ratio_digits(172.3, 158.1, 186.4) == 3
    d = ratio_digits(1.000161, 1.0000567, 1.000278)
    assert d == 5 and [f"{v:.{d}g}" for v in (1.000161, 1.0000567, 1.000278)] == ["1.0002", "1.0001", "1.0003"]
    assert ratio_digits(0.99976, 0.99945, 1.00006) == 5        # 0.99976 [0.99945, 1.0001], not [.., 1]
    assert ratio_digits(0.9, 0.85, 1.0) == 3                    # an end that is 1 prints as 1
    assert ratio_digits(1.0, 1.0, 1.0) == 3                       # equal values need no more digits
    assert ratio_digits(float("inf"), float("nan"), None) == 3    # diverged sides print as words
    assert ratio_digits(1.0 + 1e-9, 1.0, 1.0 + 2e-9) == 6


def test_the_papers_ordering_is_judged_by_paired_verdicts():
    """The paper's ordering SitL < GNS < solver only, by one rule (sitl.table1.chain_verdict) in
    Table 1 and in Table 1 as its authors ran it (sitl/study.py's paper_ordering, from per-window
    MSE_20 on the same windows)."""
    from sitl.study import paper_ordering
    from sitl.table1 import chain_verdict

    assert chain_verdict(["lower", "lower"]) == "holds"
    assert chain_verdict(["lower", stats.EQUAL]) == "does not hold"
    assert chain_verdict(["higher", "lower"]) == "does not hold"
    assert chain_verdict(["lower", "undecided"]) == "undecided"
    assert chain_verdict([]) == "undecided"
    rng = np.random.default_rng(0)
    hard = rng.uniform(0.5, 2.0, 40)          # a window's difficulty, shared by every model
    sitl, gns, solver = 1e-7 * hard, 1e-5 * hard, 1e-3 * hard
    assert paper_ordering(sitl, gns, solver, 500).startswith("holds (SitL vs GNS lower, GNS vs solver only lower")
    # the same mean on every window: equal within the margin, so the chain does not hold
    assert paper_ordering(gns, gns * (1 + 1e-4), solver, 500).startswith("does not hold (SitL vs GNS equal")
    assert paper_ordering(gns, sitl, solver, 500).startswith("does not hold (SitL vs GNS higher")
    # a diverged model leaves its steps undecided, never "holds"
    assert paper_ordering(sitl, np.where(np.arange(40) == 3, np.nan, gns), solver, 500).startswith("undecided")
    # few windows never decide
    assert paper_ordering(sitl[:3], gns[:3], solver[:3], 500).startswith("undecided")


_E_KIN = """
import json
import numpy as np
from sitl import common  # noqa: F401  (sets LagrangeBench up first)
import jax.numpy as jnp
from jax_md import space
from lagrangebench.evaluate.metrics import MetricsComputer

out = {}
for n in (20, 40):                      # 20 x 40 = 800 and 40 x 80 = 3200 particles in the 1 x 2 box
    dx = 1.0 / n
    x, y = np.meshgrid((np.arange(n) + 0.5) * dx, (np.arange(2 * n) + 0.5) * dx, indexing="ij")
    r0 = np.stack([x.ravel(), y.ravel()], 1)
    meta = {"dt": 0.001, "write_every": 20, "dx": dx, "dim": 2}
    u = np.stack([np.sin(np.pi * r0[:, 1]), 0.0 * r0[:, 1]], 1)      # u = (sin(pi y), 0)
    target = jnp.asarray(np.stack([r0 + k * 0.02 * u for k in range(3)]))
    pred = jnp.asarray(np.stack([r0 + k * 0.02 * 1.1 * u for k in range(3)]))   # 10 % too fast
    disp, _ = space.free()
    m = MetricsComputer(["e_kin"], disp, meta, input_seq_length=2, stride=1)(pred, target)["e_kin"]
    out[n * 2 * n] = {"target": float(m["target"][0]), "mse": float(m["mse"])}
print(json.dumps(out))
"""


def test_lagrangebenchs_e_kin_is_an_integral_so_mse_ekin_compares_across_particle_counts():
    """sitl/table1.py says MSE_Ekin on 800 particles stands beside the paper's on 3200: LagrangeBench's
    MetricsComputer multiplies its sum over particles by dx^dim (issue 39 said the columns could not be
    compared, reading the sum alone). Checked on LagrangeBench's own code:
    u = (sin(pi y), 0) in the 1 x 2 box, E_kin = integral of |u|^2 = 1 at both resolutions, and the
    MSE_Ekin of a rollout 10 % too fast, (1.21 - 1)^2 = 0.0441, the same at both."""
    import json
    import subprocess

    from sph_test_helpers import ROOT, require_lb_env, sitl_env

    require_lb_env()
    proc = subprocess.run([str(ROOT / ".venv-lb" / "bin" / "python"), "-c", _E_KIN], cwd=ROOT, env=sitl_env(),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    for n in ("800", "3200"):
        assert out[n]["target"] == pytest.approx(1.0, rel=1e-3), out
        assert out[n]["mse"] == pytest.approx(0.21**2, rel=1e-3), out
