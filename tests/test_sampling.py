"""Sampling: the per-sample seeding contract, the distributions (against independent CDFs),
independence, mistuning, and validation messages."""

import numpy as np
import pytest
from scipy import special, stats

from mcfric import sampling
from mcfric.sampling import Fixed, LogNormal, Normal, Sampler, TruncNormal, Uniform

ULP = 2.0 ** -54


def reference_uniforms(seed, i, n):
    """Sample i's block, derived from the documented contract via SeedSequence.spawn."""
    child = np.random.SeedSequence(seed).spawn(i + 1)[i]
    return np.random.Generator(np.random.PCG64(child)).random(n) + ULP


def test_contract_spawned_children_and_block_layout():
    s = Sampler(seed=1234, n_dampers=3, mu0=Uniform(0.0, 1.0), kc=Uniform(0.0, 15000.0),
                N0=Uniform(0.1, 0.75))
    d = s.draw([0, 5, 17])
    for row, i in enumerate([0, 5, 17]):
        u = reference_uniforms(1234, i, 9)
        np.testing.assert_array_equal(d.mu0[row], u[0:3])
        np.testing.assert_array_equal(d.kc[row], 15000.0 * u[3:6])
        np.testing.assert_array_equal(d.N0[row], 0.1 + 0.65 * u[6:9])
    assert d.modal_freq_hz is None
    # a float index drew sample 1 for 1.5
    with pytest.raises(ValueError, match="index: expected integer sample numbers"):
        s.draw(np.array([1.5]))
    # uniforms too (1.7 was sample 1); 2**64 - 1 wrapped to -1 ("must be >= 0"); a 2-d
    # index was flattened
    for bad, words in (([1.7], "integer sample numbers"), ([-1], "0..2\\*\\*63 - 1, got -1"),
                       (np.array([2**64 - 1], np.uint64), "got 18446744073709551615"),
                       ([[0, 1]], "shape \\(1, 2\\)"), ([True], "dtype bool")):
        for call in (s.uniforms, s.draw):
            with pytest.raises(ValueError, match="^index: .*" + words):
                call(bad)


def test_a_sample_does_not_depend_on_its_chunk_or_order():
    s = Sampler(seed=7, n_dampers=7, kc=TruncNormal(6000.0, 1500.0, 0.0, 15000.0),
                N0=LogNormal(0.5, 0.2), modal_freq_hz=[[16.2, 105.8]] * 8, mistuning=0.02)
    whole = s.draw(np.arange(100))
    for idx in ([37], [99, 3, 50], np.arange(64, 100)):
        part = s.draw(idx)
        for name in ("mu0", "kc", "N0", "modal_freq_hz"):
            np.testing.assert_array_equal(getattr(part, name), getattr(whole, name)[idx])


def test_changing_one_distribution_leaves_the_others_alone():
    a = Sampler(seed=3, n_dampers=2).draw(np.arange(20))
    b = Sampler(seed=3, n_dampers=2, kc=Fixed(5000.0), N0=Normal(0.5, 0.1)).draw(np.arange(20))
    np.testing.assert_array_equal(a.mu0, b.mu0)
    assert np.all(b.kc == 5000.0)


def test_seeds_differ():
    a = Sampler(seed=0, n_dampers=1).draw(np.arange(50))
    b = Sampler(seed=1, n_dampers=1).draw(np.arange(50))
    assert not np.any(a.mu0 == b.mu0)


def test_paper_defaults():
    d = Sampler(seed=0, n_dampers=7).draw(np.arange(500))
    assert d.mu0.shape == (500, 7)
    assert 0 < d.mu0.min() and d.mu0.max() < 1
    assert 0 < d.kc.min() and d.kc.max() < 15000
    assert np.all(d.N0 == 0.5)


def _pooled(dist, n=800, nd=5, seed=11):
    return Sampler(seed=seed, n_dampers=nd, mu0=dist).draw(np.arange(n)).mu0


def _ks(x, cdf):
    return stats.kstest(np.ravel(x), cdf).pvalue


@pytest.mark.parametrize("dist, cdf", [
    (Uniform(0.2, 0.9), stats.uniform(0.2, 0.7).cdf),
    (LogNormal(6000.0, 0.3),
     lambda x: special.ndtr(np.log(np.maximum(x, 1e-300) / 6000.0) / 0.3)),
    # far from 0 the conditioning is invisible: plain normal CDF
    (Normal(0.6, 0.05), lambda x: special.ndtr((x - 0.6) / 0.05)),
    # independent closed form of the truncated normal CDF
    (TruncNormal(0.4, 0.3, 0.1, 0.8),
     lambda x: (special.ndtr((np.clip(x, 0.1, 0.8) - 0.4) / 0.3) - special.ndtr(-1.0))
     / (special.ndtr(4.0 / 3.0) - special.ndtr(-1.0))),
    (TruncNormal(5000.0, 3000.0, 4800.0, np.inf),
     lambda x: (special.ndtr((np.maximum(x, 4800.0) - 5000.0) / 3000.0)
                - special.ndtr(-200 / 3000)) / (1 - special.ndtr(-200 / 3000))),
])
def test_distribution_matches_reference_cdf(dist, cdf):
    x = _pooled(dist)
    assert _ks(x, cdf) > 1e-3


def test_normal_is_conditioned_on_nonnegative():
    x = _pooled(Normal(0.3, 0.1), n=2000)
    assert x.min() >= 0
    ref = lambda v: ((special.ndtr((np.maximum(v, 0) - 0.3) / 0.1) - special.ndtr(-3))
                     / (1 - special.ndtr(-3)))
    assert _ks(x, ref) > 1e-3


def test_truncnormal_limits_are_respected():
    x = _pooled(TruncNormal(6000.0, 5000.0, 4800.0, 8000.0))
    assert x.min() >= 4800.0 and x.max() <= 8000.0


def test_fixed_is_exact():
    assert np.all(_pooled(Fixed(0.75)) == 0.75)


def test_independent_across_dampers():
    x = _pooled(Uniform(0.0, 1.0), n=4000, nd=4)
    r = np.corrcoef(x.T)
    off = r[~np.eye(4, dtype=bool)]
    assert np.max(np.abs(off)) < 0.06      # ~4 standard errors at n = 4000


def test_mistuning_per_beam_and_per_mode():
    f0 = np.array([[16.2, 105.8]] * 8)
    for per in ("beam", "mode"):
        d = Sampler(seed=5, n_dampers=7, modal_freq_hz=f0, mistuning=0.03,
                    mistuning_per=per).draw(np.arange(3000))
        ratio = d.modal_freq_hz / f0
        assert ratio.shape == (3000, 8, 2)
        assert np.all(ratio > 0)
        assert abs(np.std(ratio - 1) / 0.03 - 1) < 0.05
        assert abs(np.mean(ratio - 1)) < 0.002
        same = np.allclose(ratio[..., 0], ratio[..., 1])
        assert same == (per == "beam")
        # beams of one sample are independent of each other
        assert abs(np.corrcoef(ratio[:, 0, 0], ratio[:, 1, 0])[0, 1]) < 0.06


def test_mistuning_zero_means_nominal():
    d = Sampler(seed=5, n_dampers=1, modal_freq_hz=[[16.2, 105.8]] * 2).draw([0, 1])
    assert d.modal_freq_hz is None


@pytest.mark.parametrize("make, starts", [
    (lambda: Uniform(0.8, 0.5), "high: expected a number >= low"),
    (lambda: Uniform(-1.0, 0.5), "low: expected a number >= 0"),
    (lambda: Fixed(float("nan")), "value: expected a finite number"),
    (lambda: Normal(0.5, 0.3), "std: expected <= mean/3"),
    (lambda: TruncNormal(0.5, 0.0, 0.0, 1.0), "std: expected a number > 0"),
    (lambda: TruncNormal(0.5, 0.1, 0.6, 0.6), "high: expected a number > low"),
    (lambda: LogNormal(0.0, 0.1), "median: expected a number > 0"),
    (lambda: LogNormal(1.0, True), "sigma: expected a number"),
    (lambda: sampling.distribution("gamma"), "dist: expected one of"),
    (lambda: sampling.distribution("uniform", low=0.0), "high: missing"),
    (lambda: sampling.distribution("fixed", value=1.0, low=0.0), "low: not a parameter"),
    (lambda: Sampler(seed=-1, n_dampers=1), "seed: expected an integer >= 0"),
    (lambda: Sampler(seed=0, n_dampers=True), "n_dampers: expected an integer >= 1"),
    (lambda: Sampler(seed=0, n_dampers=1, modal_freq_hz=[[16.2]] * 2, mistuning=0.2),
     "mistuning: expected 0..0.1"),
    (lambda: Sampler(seed=0, n_dampers=1, mistuning=0.01), "modal_freq_hz: needed"),
    # inf drawn as inf, text parsed, booleans read as 1 Hz, the imaginary part dropped, an
    # empty table taken, and numpy's words for a ragged list (naming nothing), before
    *[(lambda v=v: Sampler(seed=0, n_dampers=1, modal_freq_hz=v, mistuning=0.05),
       "modal_freq_hz: ") for v in ([[16.2, np.inf]], [["16", "100"]], [[True, True]],
                                    [[16.2 + 1j]], np.zeros((0, 2)), [[16.2], [1.0, 2.0]],
                                    [[16.2, 1e300]])],
])
def test_validation_messages_name_the_parameter(make, starts):
    with pytest.raises(ValueError) as e:
        make()
    assert str(e.value).startswith(starts)


@pytest.mark.parametrize("dist", [Fixed(1.0), Uniform(0.0, 1.0), Normal(1.0, 0.1), Normal(1.0, 0.0),
                                  TruncNormal(1.0, 0.1, 0.0, 2.0), LogNormal(1.0, 0.3)])
def test_ppf_takes_uniforms_in_the_open_unit_interval_only(dist):
    """A uniform outside (0, 1) gave a value outside the distribution (Uniform(0, 1) drew
    2.0 for 2.0, Fixed drew its value for NaN)."""
    assert np.all(np.isfinite(dist.ppf([1e-12, 0.5, 1 - 1e-12])))
    for bad in ([2.0], [np.nan], [0.0], [1.0], [-0.5], ["0.5"]):
        with pytest.raises(ValueError, match="^u: expected"):
            dist.ppf(bad)
