"""Confidence intervals of quantiles: coverage by simulation, and scipy's quantile test."""

import numpy as np
import pytest
from scipy import stats

from mcfric.quantiles import quantile_interval


@pytest.mark.parametrize("n, p", [(30, 0.5), (200, 0.95), (2000, 0.95)])
def test_intervals_hold_the_true_quantile_at_least_as_often_as_claimed(n, p):
    # known populations, one continuous and one with ties (a plateau, as the two-beam
    # members' peaks have): the interval must hold the true quantile in >= 95 % of draws
    rng = np.random.default_rng(7)
    trials = 1500
    for draw, true in ((lambda: rng.lognormal(size=n), np.exp(stats.norm.ppf(p))),
                       (lambda: np.where(rng.random(n) < 0.955, 1.0, 1.0 + rng.random(n)),
                        1.0)):
        hits = 0
        for _ in range(trials):
            lo, hi = quantile_interval(draw(), p, 0.95)
            hits += lo <= true <= hi
        # the binomial's 3-sigma margin below 95 %
        assert hits / trials >= 0.95 - 3 * np.sqrt(0.95 * 0.05 / trials)


def test_intervals_equal_scipys_quantile_test():
    if not hasattr(stats, "quantile_test"):
        pytest.skip("scipy.stats.quantile_test is newer than this scipy")
    rng = np.random.default_rng(3)
    for n in (15, 120, 2000):
        x = rng.gamma(2.0, size=n)
        for p in (0.5, 0.9, 0.95):
            ref = stats.quantile_test(x, q=np.median(x), p=p).confidence_interval(0.95)
            lo, hi = quantile_interval(x, p, 0.95)
            assert lo == ref.low
            # scipy gives NaN where the sample cannot close the upper side
            assert hi == ref.high or (np.isnan(ref.high) and hi == np.inf)


def test_small_empty_and_bad_input():
    assert quantile_interval([1.0, 2.0], 0.95) == (1.0, np.inf)
    assert all(np.isnan(quantile_interval([np.nan], 0.5)))
    with pytest.raises(ValueError, match="0 < p"):
        quantile_interval([1.0], 1.0)
    # -1 lower estimates gave (-inf, 3); a 2-d array was flattened silently
    with pytest.raises(ValueError, match="raised: expected an integer >= 0, got -1"):
        quantile_interval([1.0, 2.0, 3.0], 0.5, raised=-1)
    with pytest.raises(ValueError, match=r"values: expected shape \(n,\), got \(2, 2\)"):
        quantile_interval([[1.0, 2.0], [3.0, 4.0]], 0.5)


@pytest.mark.parametrize("k", [1, 10])
def test_intervals_with_lower_estimates_still_hold_the_quantile(k):
    """k members given below their true values (peaks not refined, at 0.3-1 of them):
    with ``raised=k`` the interval holds the true quantile as often as claimed; the
    worst case for the upper end is the k largest members lowered."""
    rng = np.random.default_rng(11)
    n, trials = 400, 1500
    for p in (0.5, 0.95):
        true = np.exp(stats.norm.ppf(p))
        hits = 0
        for _ in range(trials):
            x = rng.lognormal(size=n)
            top = np.argsort(x)[-k:]
            x[top] *= rng.uniform(0.3, 1.0, k)
            lo, hi = quantile_interval(x, p, 0.95, raised=k)
            hits += lo <= true <= hi
        assert hits / trials >= 0.95 - 3 * np.sqrt(0.95 * 0.05 / trials)


def test_intervals_with_unknown_members_still_hold_the_quantile():
    """m members without a value (a member with no converged point has no peak): with
    ``unknown=m`` the interval holds the true quantile as often as claimed, whether the
    values lost were the m smallest or the m largest (the worst cases of each end);
    without it, losing the smallest moves the lower end above the quantile too often."""
    rng = np.random.default_rng(12)
    n, trials, m = 400, 1500, 10
    need = 0.95 - 3 * np.sqrt(0.95 * 0.05 / trials)
    for p in (0.5, 0.95):
        true = np.exp(stats.norm.ppf(p))
        hits = {"smallest": 0, "largest": 0, "ignored": 0}
        for _ in range(trials):
            x = np.sort(rng.lognormal(size=n))
            for lost, kept in (("smallest", x[m:]), ("largest", x[:-m])):
                lo, hi = quantile_interval(kept, p, 0.95, unknown=m)
                hits[lost] += lo <= true <= hi
            lo, hi = quantile_interval(x[m:], p, 0.95)
            hits["ignored"] += lo <= true <= hi
        assert hits["smallest"] / trials >= need and hits["largest"] / trials >= need, hits
        if p == 0.5:
            assert hits["ignored"] / trials < need, hits


def test_unknown_members_count_in_the_sample_size():
    x = np.arange(1.0, 101.0)
    # the order statistics of 103 members (binomial, written out), the lower one 3 lower
    k = np.arange(105)
    l_ = np.flatnonzero(stats.binom.cdf(k - 1, 103, 0.5) <= 0.025)[-1]
    u_ = np.flatnonzero(stats.binom.sf(k - 1, 103, 0.5) <= 0.025)[0]
    assert quantile_interval(x, 0.5, 0.95, unknown=3) == (x[l_ - 3 - 1], x[u_ - 1])
    assert quantile_interval(x, 0.5, 0.95, raised=2, unknown=3) == (x[l_ - 4], x[u_ + 1])
    assert quantile_interval([1.0, 2.0], 0.5, unknown=5)[0] == -np.inf
    with pytest.raises(ValueError, match="unknown"):
        quantile_interval(x, 0.5, unknown=-1)
