"""Property-based tests (hypothesis): random inputs over wide ranges.

* The kernel: random friction parameters over 12 decades, frequencies on and near the
  resonances, identical and mistuned beams, chains and rings. Every point is either flagged
  as not converged (NaN) or satisfies the single-harmonic equations when they are checked
  by the plain reference of tests/naive.py. A wrong unflagged number fails.
* Configurations: random valid ones run to a complete file; random invalid ones give one
  line on stderr, exit code 2, and no file.

The examples are derandomised (the same ones on every run), so CI is deterministic; the
counts are in ``EXAMPLES``.
"""

import json
import math

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mcfric
from mcfric import cli
from mcfric.model import TABLE_1, Excitation, Model

from . import naive
from .conftest import naive_beams, naive_pairs

EXAMPLES = {"kernel": 300, "valid_config": 60, "invalid_config": 200}
SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])

decades = st.floats(-6.0, 6.0)


@st.composite
def kernel_case(draw):
    n_beams = draw(st.integers(2, 4))
    ring = n_beams >= 3 and draw(st.booleans())
    model = Model.identical(TABLE_1, n_beams, topology="circular" if ring else "linear",
                            excitation=Excitation("single", draw(st.floats(0.01, 10.0)),
                                                  beam=1))
    nd = model.n_dampers
    n_s = draw(st.integers(1, 3))
    par = {k: 10.0 ** np.array(draw(st.lists(decades, min_size=n_s * nd,
                                              max_size=n_s * nd))).reshape(n_s, nd)
           for k in ("mu0", "kc", "N0")}
    # frequencies on, near and between the modes (and the coupled modes around them)
    modes = np.array(TABLE_1.freq_hz)
    offsets = draw(st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=6))
    picks = draw(st.lists(st.integers(0, len(modes) - 1), min_size=len(offsets),
                          max_size=len(offsets)))
    f = np.sort(modes[picks] * (1.0 + np.array(offsets)))
    mistuning = draw(st.sampled_from([0.0, 0.02, 0.1]))
    modal = None
    if mistuning:
        rng = np.random.default_rng(draw(st.integers(0, 2**31)))
        modal = modes[None, None, :] * (1.0 + mistuning * rng.standard_normal((n_s, n_beams,
                                                                              1)))
    return model, f, par, modal


def describing_function(s, kc):
    """tests/naive.py's describing function, with the real part summed as a power series
    in sqrt(s) for small s, where the closed form cancels (derived independently of the
    kernel's series; the two agree to 2e-11 at s = 1e-3)."""
    if 0 < s < 1e-3:
        x = math.sqrt(s)
        re = (16 / 3 * x**3 - 8 / 5 * x**5 - 2 / 7 * x**7) / math.pi
        return kc * complex(re, 4 / math.pi * s * (1 - s))
    return naive.describing_function(s, kc)


def residual_check(model, f, par, modal, r, i, k):
    """Relative error of point (i, k) against the plain reference: the slip ratios give the
    describing functions, the plain linear solve gives q and y, and both must agree."""
    beams = naive_beams(model)
    if modal is not None:
        for b, bm in enumerate(beams):
            bm["freq_hz"] = modal[i, b]
    omega = 2 * np.pi * f[k]
    kc, fs = par["kc"][i], par["mu0"][i] * par["N0"][i]
    s = r.s[i, k]
    K = np.array([describing_function(s[j], kc[j]) for j in range(len(kc))])
    sol = naive.beam_space_response(omega, beams, naive_pairs(model), model.force, K)
    y = sol["y_output"]
    err = np.max(np.abs(y - r.response[i, k])) / max(np.max(np.abs(y)), 1e-300)
    for j in range(len(kc)):
        amp = abs(sol["q"][j])
        if 0 < s[j] < 1:                        # slipping: s = fs / (kc |q|)
            err = max(err, abs(fs[j] / (kc[j] * amp) - s[j]) / s[j])
        elif s[j] >= 1 and math.isfinite(s[j]):  # stuck: kc |q| <= fs
            err = max(err, max(0.0, kc[j] * amp - fs[j]) / fs[j])
    return err


@settings(max_examples=EXAMPLES["kernel"], **SETTINGS)
@given(kernel_case())
def test_every_point_is_flagged_or_satisfies_its_equations(case):
    model, f, par, modal = case
    r = mcfric.solve(model, f, par["mu0"], par["kc"], par["N0"], modal_freq_hz=modal)
    ok = r.converged
    assert np.all(np.isnan(r.response[~ok]))                 # flagged points: no numbers
    assert r.n_not_converged == int(np.count_nonzero(~ok))
    for i, k in zip(*np.nonzero(ok)):
        assert np.all(np.isfinite(r.response[i, k]))
        assert residual_check(model, f, par, modal, r, i, k) < 1e-6, (i, k)


# -- configurations --------------------------------------------------------------------

def dist(draw, lo, hi, bounded):
    """A distribution's TOML lines; ``bounded``: one with an upper limit and some value
    above 0 (what the bounds' "auto" limits need)."""
    kinds = ["fixed", "uniform", "truncnormal"] + ([] if bounded else ["lognormal", "normal"])
    kind = draw(st.sampled_from(kinds))
    a = draw(st.floats(lo, hi))
    b = draw(st.floats(lo, hi))
    a, b = min(a, b), max(a, b)
    if kind == "fixed":
        return f'dist = "fixed"\nvalue = {max(a, 1e-3 * hi) if bounded else a!r}'
    if kind == "uniform":
        return f'dist = "uniform"\nlow = {a!r}\nhigh = {b + 1e-3 * (hi - lo)!r}'
    if kind == "normal":
        mean = max(a, 1e-3 * hi)
        return (f'dist = "normal"\nmean = {mean!r}\n'
                f'std = {draw(st.floats(1e-3, 1.0)) * mean / 3!r}')
    if kind == "lognormal":
        return (f'dist = "lognormal"\nmedian = {max(a, 1e-3 * hi)!r}\n'
                f'sigma = {draw(st.floats(0.0, 1.0))!r}')
    return (f'dist = "truncnormal"\nmean = {a!r}\nstd = {draw(st.floats(1e-3, 1.0)) * hi!r}\n'
            f'low = 0.0\nhigh = {hi!r}')


@st.composite
def valid_config(draw):
    n_beams = draw(st.integers(2, 5))
    f_min = draw(st.floats(5.0, 100.0))
    bounds = draw(st.booleans())
    topology = draw(st.sampled_from(["linear", "circular"])) if n_beams >= 3 else "linear"
    lines = [
        "[model]",
        f"n_beams = {n_beams}",
        f'topology = "{topology}"',
        "[excitation]",
        f'pattern = "{draw(st.sampled_from(["single", "mode"]))}"',
        f"mode = {draw(st.integers(0, n_beams - 1))}",    # m >= n_beams is refused
        f"F0 = {draw(st.floats(0.01, 5.0))!r}",
        "[frequency]",
        f"f_min = {f_min!r}",
        f"f_max = {f_min + draw(st.floats(1.0, 100.0))!r}",
        f"n = {draw(st.integers(2, 12))}",
        f'spacing = "{draw(st.sampled_from(["linear", "log"]))}"',
        "[sampling]",
        f"samples = {draw(st.integers(1, 6))}",
        f"seed = {draw(st.integers(0, 2**32))}",
        f"mistuning = {draw(st.sampled_from([0.0, 0.01, 0.05]))!r}",
        "[sampling.mu0]", dist(draw, 0.0, 1.0, bounds),
        "[sampling.kc]", dist(draw, 0.0, 20000.0, bounds),
        "[sampling.N0]", dist(draw, 0.0, 2.0, bounds),
        "[metric]",
        f'quantity = "{draw(st.sampled_from(["displacement", "velocity", "acceleration"]))}"',
        "[peaks]",
        f"enabled = {str(draw(st.booleans())).lower()}",
        "[bounds]",
        f"enabled = {str(bounds).lower()}",
        "[output]",
        f"keep_response = {str(draw(st.booleans())).lower()}",
    ]
    return "\n".join(lines) + "\n"


@settings(max_examples=EXAMPLES["valid_config"], **SETTINGS)
@given(valid_config())
def test_random_valid_configurations_run(tmp_path_factory, text):
    d = tmp_path_factory.mktemp("valid")
    cfg = d / "c.toml"
    cfg.write_text(text)
    out = d / "r.h5"
    rc = cli.main(["run", str(cfg), "-o", str(out), "--no-progress", "--no-figure"])
    assert rc == 0, text
    with h5py.File(out) as h:
        assert h.attrs["complete"] == 1
        conv = h["converged"][...]
        m = h["metric"][...]
        assert np.all(np.isfinite(m[conv])) and np.all(np.isnan(m[~conv]))


BAD_VALUES = [-1, -1e300, float("nan"), float("inf"), "x", "", True, [1, 2], {"a": 1}, 0,
              1e300]
KEYS = ["model.n_beams", "model.topology", "excitation.F0", "excitation.pattern",
        "frequency.f_min", "frequency.f_max", "frequency.n", "frequency.spacing",
        "sampling.samples", "sampling.seed", "sampling.mistuning", "sampling.mu0",
        "sampling.kc", "metric.quantity", "metric.beams", "solver.tol", "solver.max_iter",
        "solver.harmonics", "peaks.count", "peaks.rtol", "bounds.k_max", "bounds.F_lim",
        "run.threads", "run.chunk", "output.keep_response", "model.name"]
#: The drawn (key, value) pairs the configuration reference allows (docs/configuration.md):
#: every other pair must be refused.
ALLOWED = {("sampling.seed", int, 0), ("sampling.mistuning", int, 0),
           ("metric.beams", list, (1, 2)), ("bounds.F_lim", float, 1e300),
           ("run.threads", int, 0), ("run.chunk", int, 0),
           ("output.keep_response", bool, True), ("model.name", str, "x")}


def allowed(key, value):
    v = tuple(value) if isinstance(value, list) else value
    return any(k == key and type(value) is t and v == a for k, t, a in ALLOWED)


def toml_value(v):
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(v)


@settings(max_examples=EXAMPLES["invalid_config"], **SETTINGS)
@given(st.sampled_from(KEYS), st.sampled_from(BAD_VALUES))
def test_random_bad_values_give_one_line_or_a_complete_run(tmp_path_factory, capsys, key,
                                                           value):
    """A bad value is refused in one line with exit 2 and no file. The few drawn values
    that are in fact allowed (a seed of 0, a name "x", ...: ``ALLOWED``, from the
    configuration reference) must run to a complete file holding that value: never a
    traceback, never a half-written output, never a bad value accepted."""
    d = tmp_path_factory.mktemp("invalid")
    section, name = key.split(".")
    tables = {"model": {"preset": '"two-beam"'}}
    tables.setdefault(section, {})[name] = toml_value(value)
    cfg = d / "c.toml"
    cfg.write_text("".join(f"[{t}]\n" + "".join(f"{k} = {v}\n" for k, v in kv.items())
                           for t, kv in tables.items()))
    capsys.readouterr()
    out = d / "r.h5"
    # small runs, without masking the key drawn (the flags override the file)
    size = {"sampling.samples": ["--n-freq", "3"], "frequency.n": ["--samples", "2"]}.get(
        key, ["--samples", "2", "--n-freq", "3"])
    rc = cli.main(["run", str(cfg), *size, "-o", str(out), "--no-progress", "--no-figure"])
    err = capsys.readouterr().err.strip()
    assert rc == (0 if allowed(key, value) else 2), (key, value, err)
    if rc == 2:
        assert len(err.splitlines()) == 1 and err.startswith("mcfric: error:"), err
        assert sorted(p.name for p in d.iterdir()) == ["c.toml"]
    else:
        with h5py.File(out) as h:
            assert h.attrs["complete"] == 1
            stored = json.loads(h.attrs["config_json"])[section][name]
        assert stored == value, (key, value, stored)


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_example_counts_are_what_the_docs_say(name):
    """The counts that docs/guarantees.md quotes, each in its own phrase."""
    text = (__import__("pathlib").Path(__file__).parents[1] / "docs" /
            "guarantees.md").read_text()
    phrase = {"kernel": "the kernel, {} random cases",
              "valid_config": "{} random valid configurations",
              "invalid_config": "{} random (key, bad value) pairs"}[name]
    assert phrase.format(EXAMPLES[name]) in " ".join(text.split())
