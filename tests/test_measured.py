"""Measured data: a simulated member exported to UFF 58 and read back as "measured" lies
100 % inside the bounds; normalisation is the friction law's homogeneity; CSV and foreign
UFF 58 files (FRFs, units, quantities); fraction-inside counting; one-line errors."""

import gc
import math
import sys

import numpy as np
import pytest

import mcfric
from mcfric.measured import (
    METRIC,
    Measurement,
    export_uff58,
    fraction_inside,
    interpolate_log,
    normalise,
    read_measured,
)
from mcfric.modal_io import write_modal_table_uff55

pyuff = pytest.importorskip("pyuff")

NODES = [102, 202]          # response node of beam 1, beam 2
FREQ = np.linspace(9.3, 148.7, 61)   # values that lose digits in UFF's E13.5 abscissa
N_SAMPLES = 16
MEMBER = 5


def one_line(excinfo, *words):
    msg = str(excinfo.value)
    assert "\n" not in msg, msg
    for w in words:
        assert w.lower() in msg.lower(), msg
    return msg


@pytest.fixture(scope="module")
def ensemble():
    """A small two-beam ensemble (paper's distributions) at F0 = 0.22 N, N0 = 0.5 N."""
    rng = np.random.default_rng(2024)
    mu0 = rng.uniform(0, 1, (N_SAMPLES, 1))
    kc = rng.uniform(0, 15000, (N_SAMPLES, 1))
    res = mcfric.solve(mcfric.two_beam(0.22), FREQ, mu0=mu0, kc=kc, N0=0.5)
    assert res.n_not_converged == 0
    return res, mu0, kc


def envelope(amp):
    """Stand-in bounds: [0.999 min, 1.001 max] over the ensemble (axis 0)."""
    return 0.999 * amp.min(axis=0), 1.001 * amp.max(axis=0)


# ---------------------------------------------------------------- the must-show

@pytest.mark.parametrize("function", ["frf", "response"])
def test_exported_member_lies_inside_the_bounds(tmp_path, ensemble, function):
    # Stand-in bounds: the envelope of an ensemble containing the member. Switch to the
    # equivalent-linear bounds (mcfric.bounds) when they exist: the member must lie inside
    # those too.
    res, _, _ = ensemble
    member = res.response[MEMBER]                               # (n_f, 2) complex, m
    data = member if function == "frf" else np.abs(member)
    path = tmp_path / "member.uff"
    info = export_uff58(path, FREQ, data, force_n=0.22, nodes=NODES, function=function)
    assert info == {"records": 2, "points": 2 * FREQ.size, "dropped": 0}
    (meas,) = read_measured(path, nodes=NODES)
    assert meas.beams == (1, 2) and meas.kind == "sweep" and meas.force_n == 0.22
    assert meas.quantity == "displacement" and meas.is_complex == (function == "frf")
    # the values themselves: abscissa to E13.5, ordinate to 12 digits
    np.testing.assert_allclose(meas.frequency_hz, FREQ, rtol=5e-6)
    np.testing.assert_allclose(meas.response, data, rtol=1e-10)

    lo, up = envelope(np.abs(res.response))                     # per beam, (n_f, 2)
    inside = fraction_inside(meas, FREQ, lo, up)
    assert inside.per_beam == {1: 1.0, 2: 1.0} and inside.overall == 1.0
    assert inside.compared() == 2 * FREQ.size
    # the metric M against the envelope of M
    lo_m, up_m = envelope(res.metric())
    inside_m = fraction_inside(meas.metric(), FREQ, lo_m, up_m)
    assert inside_m.per_beam == {METRIC: 1.0}

    # ...and the test can fail: 3 % more response leaves the envelope somewhere
    louder = fraction_inside(meas.scaled(1.03), FREQ, lo, up)
    assert louder.overall < 1.0 and sum(louder.above.values()) > 0


def test_normalisation_is_the_homogeneity_of_the_friction_law(tmp_path, ensemble):
    res, mu0, kc = ensemble
    # the "rig" ran member MEMBER at twice the force and twice the preload
    rig = mcfric.solve(mcfric.two_beam(0.44), FREQ, mu0=mu0[MEMBER], kc=kc[MEMBER], N0=1.0)
    path = tmp_path / "rig.uff"
    export_uff58(path, FREQ, np.abs(rig.response[0]), force_n=0.44, nodes=NODES,
                 kind="stepped")
    (meas,) = read_measured(path, nodes=NODES)
    assert meas.kind == "stepped" and meas.force_n == 0.44

    lo, up = envelope(np.abs(res.response))
    assert fraction_inside(meas, FREQ, lo, up).overall < 0.9   # not comparable as is

    norm, report = normalise(meas, 0.22, N0_meas=1.0)
    assert report.c == pytest.approx(0.5, rel=1e-15)
    assert report.N0_equivalent == pytest.approx(0.5, rel=1e-15)
    text = report.text()
    assert "c = F0/F_meas = 0.22/0.44 = 0.5" in text and "0.5 N0" in text and "\n" not in text
    assert norm.force_n == 0.22
    # c times the rig's response is the response at F0 with preload c N0
    np.testing.assert_allclose(norm.response, np.abs(res.response[MEMBER]), rtol=1e-7)
    assert fraction_inside(norm, FREQ, lo, up).overall == 1.0
    # a force level whose factor overflows is refused, not returned as a response of inf
    tiny = Measurement(FREQ, meas.response, meas.beams, force_n=1e-310)
    with pytest.raises(ValueError, match="puts the response out of range"):
        normalise(tiny, 0.22)


def test_percentiles_round_trip(tmp_path, ensemble):
    res, _, _ = ensemble
    pct = [5.0, 50.0, 95.0]
    p_metric = np.percentile(res.metric(), pct, axis=0)            # (3, n_f)
    path = tmp_path / "pct.uff"
    info = export_uff58(path, FREQ, p_metric, force_n=0.22, percentiles=pct, nodes=[900])
    assert info["records"] == 3
    back = read_measured(path, nodes={900: METRIC})
    assert [m.percentile for m in back] == pct
    for m, want in zip(back, p_metric):
        assert m.beams == (METRIC,) and not m.is_complex
        np.testing.assert_allclose(m.response[:, 0], want, rtol=1e-10)
    # per-beam percentiles: one record per (percentile, beam)
    p_beam = np.percentile(np.abs(res.response), pct, axis=0)      # (3, n_f, 2)
    export_uff58(path, FREQ, p_beam, force_n=0.22, percentiles=pct, nodes=NODES,
                 overwrite=True)
    back = read_measured(path, nodes=NODES)
    assert len(back) == 3 and all(m.beams == (1, 2) for m in back)
    np.testing.assert_allclose(back[2].response, p_beam[2], rtol=1e-10)


def test_an_up_and_down_sweep_exports_and_reads_back_in_order(tmp_path):
    """Repeated frequencies (the same numbers) are no clash of 6 printed digits."""
    f = np.r_[20.0:81.0:10.0, 70.0:19.0:-10.0]
    y = np.linspace(1e-5, 2e-5, f.size)[:, None] * [1.0, 2.0]
    export_uff58(tmp_path / "ud.uff", f, y, force_n=0.5, nodes=NODES)
    (m,) = read_measured(tmp_path / "ud.uff", nodes=NODES)
    assert np.array_equal(m.frequency_hz, f)
    np.testing.assert_allclose(np.abs(m.response), y, rtol=1e-11)


def test_export_leaves_out_non_finite_points(tmp_path):
    y = np.abs(np.sin(FREQ))[:, None] * [1.0, 2.0] + 1e-6
    y[[3, 10], 0] = np.nan
    path = tmp_path / "nan.uff"
    info = export_uff58(path, FREQ, y, force_n=1.0, nodes=NODES)
    assert info["dropped"] == 2 and info["points"] == 2 * FREQ.size - 2
    (m,) = read_measured(path, nodes=NODES)
    # merged onto the union of the abscissas: NaN where beam 1 was not written
    assert m.frequency_hz.size == FREQ.size
    assert np.count_nonzero(np.isnan(m.response[:, 0])) == 2
    assert not np.any(m.response[:, 0] == 0)                  # pyuff would have written 0
    with pytest.raises(ValueError) as e:
        export_uff58(path, FREQ, y, force_n=1.0)
    one_line(e, str(path), "exists", "overwrite=True")
    # a word is a true value: overwrite="no" replaced the file
    before = path.read_bytes()
    with pytest.raises(ValueError) as e:
        export_uff58(path, FREQ, y, force_n=1.0, overwrite="no")
    one_line(e, str(path), "overwrite: expected True or False")
    assert path.read_bytes() == before


# ---------------------------------------------------------------- foreign UFF 58 files

def record(node, x, data, *, func_type=4, spec=12, denom=13, direction=3, ids=None):
    d = {"type": 58, "func_type": func_type, "rsp_node": node, "rsp_dir": direction,
         "ref_node": 1, "ref_dir": 3, "abscissa_spec_data_type": 18,
         "ordinate_spec_data_type": spec, "orddenom_spec_data_type": denom,
         "x": np.asarray(x, float), "data": np.asarray(data)}
    d.update(ids or {})
    return d


def write58(path, records, units=None):
    dsets = []
    if units is not None:
        dsets.append({"type": 164, "units_code": 5, "units_description": "mm N",
                      "temp_mode": 1, "length": units[0], "force": units[1], "temp": 1.0,
                      "temp_offset": 273.15})
    pyuff.UFF(str(path)).write_sets(dsets + records, mode="overwrite")
    return path


def test_accelerance_in_mm_from_a_test_system(tmp_path):
    # accelerance FRFs (mm/s^2 / N) with a units dataset, two beams, one extra sensor
    f = np.linspace(20, 80, 31)
    w = 2 * np.pi * f
    X = np.column_stack([1e-4 / (1 - (f / 50) ** 2 + 0.02j), 2e-5 * np.exp(1j * f / 9)])
    F = 0.5
    A_per_N = -(w ** 2)[:, None] * X / F * 1000.0                # mm/s^2 per N
    path = write58(tmp_path / "rig.unv",
                   [record(102, f, A_per_N[:, 0]), record(202, f, A_per_N[:, 1]),
                    record(3, f, np.ones(f.size))], units=(1000.0, 1.0))
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=NODES)
    one_line(e, str(path), "FRF", "force_n=")
    (m,) = read_measured(path, nodes={202: 2, 102: 1}, force_n=F, kind="sweep")
    assert m.quantity == "acceleration" and m.force_n == F and m.kind == "sweep"
    np.testing.assert_allclose(m.displacement().response, X, rtol=1e-9)
    np.testing.assert_allclose(m.to_quantity("velocity").response, 1j * w[:, None] * X,
                               rtol=1e-9)
    # tags in the ID lines and an argument that contradicts them
    tagged = [record(n, f, A_per_N[:, j], ids={"id4": "run 7 force_n=0.5 kind=stepped"})
              for j, n in enumerate(NODES)]
    path = write58(tmp_path / "tagged.uff", tagged, units=(1000.0, 1.0))
    (m,) = read_measured(path, nodes=NODES)
    assert m.force_n == 0.5 and m.kind == "stepped"
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=NODES, force_n=0.7)
    one_line(e, str(path), "force_n=0.5", "force_n=0.7")


def test_stepped_and_sweep_records_are_kept_apart(tmp_path):
    f1, f2 = np.array([30.0, 40.0, 50.0]), np.linspace(30, 50, 9)
    recs = [record(n, f1, np.full(3, 1e-5), func_type=0, spec=8, denom=0,
                   ids={"id4": "kind=stepped force_n=0.2"}) for n in NODES]
    recs += [record(n, f2, np.full(9, 2e-5), func_type=0, spec=8, denom=0,
                    ids={"id4": "kind=sweep force_n=0.2", "func_id": 77}) for n in NODES]
    path = write58(tmp_path / "two.uff", recs)
    # pyuff cannot write function type 12 (spectrum): make the sweep records spectra
    text = path.read_text()
    assert text.count("\n    0        77") == 2
    path.write_text(text.replace("\n    0        77", "\n   12        77"))
    ms = read_measured(path, nodes=NODES)
    assert [(m.kind, m.frequency_hz.size) for m in ms] == [("stepped", 3), ("sweep", 9)]


def test_directions_and_ambiguity(tmp_path):
    f = np.array([10.0, 20.0, 30.0])
    recs = [record(102, f, np.full(3, 1.0 + 1j), func_type=0, spec=8, denom=0,
                   direction=-3),
            record(102, f, np.full(3, 5.0 + 0j), func_type=0, spec=8, denom=0, direction=1)]
    path = write58(tmp_path / "dirs.uff", recs)
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=[102])
    one_line(e, str(path), "two records for beam 1", "direction=")
    (m,) = read_measured(path, nodes=[102], direction=3)
    np.testing.assert_array_equal(m.response[:, 0], -(1.0 + 1j))   # -Z flipped to +Z
    # +Z and -Z at one node: the direction given cannot choose, the file must be split
    both = write58(tmp_path / "both.uff", recs[:1] + [
        record(102, f, np.full(3, 2.0 + 0j), func_type=0, spec=8, denom=0, direction=3)])
    with pytest.raises(ValueError) as e:
        read_measured(both, nodes=[102], direction=3)
    one_line(e, str(both), "two records for beam 1", "both in direction +-3: split the file")
    assert "pass direction=" not in str(e.value)


@pytest.mark.parametrize("func_type, spec, words", [
    (2, 12, ["function type 2", "auto spectrum"]),
    (1, 12, ["function type 1", "time response"]),
    (0, 13, ["ordinate specific data type 13"]),
    (0, 0, ["not given", "quantity="]),
])
def test_unusable_records(tmp_path, func_type, spec, words):
    path = write58(tmp_path / "bad.uff", [record(102, [1.0, 2.0], [1.0, 2.0],
                                                 func_type=func_type, spec=spec, denom=0)])
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=[102])
    one_line(e, str(path), *words)


def test_node_mapping_errors(tmp_path):
    path = write58(tmp_path / "n.uff", [record(102, [1.0, 2.0], [1.0, 2.0], func_type=0,
                                               spec=8, denom=0)])
    with pytest.raises(ValueError) as e:
        read_measured(path)
    one_line(e, str(path), "nodes=", "response nodes in the file: 102")
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=NODES)
    one_line(e, str(path), "no record for node 202", "beam 2")
    with pytest.raises(ValueError) as e:
        read_measured(path, nodes=[7])
    one_line(e, str(path), "no dataset 58 record at the mapped nodes 7")


# ---------------------------------------------------------------- bad UFF files

def test_truncated_and_wrong_uff_files(tmp_path):
    path = tmp_path / "m.uff"
    export_uff58(path, FREQ, np.ones((FREQ.size, 2)), force_n=1.0, nodes=NODES)
    text = path.read_text()
    for cut in (len(text) - 8, int(len(text) * 0.7)):
        bad = tmp_path / f"cut{cut}.uff"
        bad.write_text(text[:cut])
        with pytest.raises(ValueError) as e:
            read_measured(bad, nodes=NODES)
        one_line(e, str(bad), "truncated")
    # a record whose data lost lines but kept its closing delimiter
    lines = text.splitlines()
    end = max(i for i, ln in enumerate(lines) if ln.strip() == "-1")
    bad = tmp_path / "short.uff"
    bad.write_text("\n".join(lines[:end - 3] + lines[end:]) + "\n")
    with pytest.raises(ValueError) as e:
        read_measured(bad, nodes=NODES)
    one_line(e, str(bad), "61 points")
    # a modal table is not a measurement
    modal = write_modal_table_uff55(tmp_path / "modes.uff", mcfric.TABLE_1)
    with pytest.raises(ValueError) as e:
        read_measured(modal, nodes=NODES)
    one_line(e, str(modal), "no dataset 58", "found dataset types: 55, 164")


@pytest.mark.parametrize("kwargs, message", [
    ({"nodes": [10**12, 5]}, "distinct node numbers in 0..2147483647"),  # field overflow
    ({"nodes": {1: 5, 2: 5}}, "distinct node numbers"),       # one node for two beams
    ({"nodes": NODES, "force_n": True}, "force_n: expected a force > 0 N"),
    ({"nodes": NODES, "ref_node": "abc"}, "ref_node"),
    ({"nodes": NODES, "name": "e.csv"}, "expected a UFF file name"),
    # two frequencies one UFF 58 text prints alike, and ones out of order
    ({"nodes": NODES, "freq": np.r_[FREQ[0], FREQ[0] * (1 + 2e-7), FREQ[2:]]},
     "9.3 and 9.30000186 Hz both print as 9.30000e+00 in UFF 58's 6 significant digits"),
    # apart in the grid: a down sweep after the up sweep
    ({"nodes": NODES, "freq": np.r_[FREQ[:31], FREQ[29::-1] * (1 + 1e-7)]}, "both print as"),
    ({"nodes": NODES, "description": "rig\nrun 12"}, "description: expected printable ASCII"),
    ({"nodes": NODES, "description": "rig kind=stepped"}, "holds a tag that read_measured"),
])
def test_export_refuses_what_would_not_read_back(tmp_path, kwargs, message):
    """Files that were written but did not read back (a node number cut to its field, two
    beams on one node, UFF text under a .csv name) are refused, nothing written."""
    kwargs = dict(kwargs)
    path = tmp_path / kwargs.pop("name", "x.uff")
    freq = kwargs.pop("freq", FREQ)
    kwargs.setdefault("force_n", 1.0)
    with pytest.raises(ValueError) as e:
        export_uff58(path, freq, np.ones((FREQ.size, 2)), **kwargs)
    one_line(e, message)
    assert not any(tmp_path.iterdir())


def test_missing_pyuff_gives_install_hint(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)
    with pytest.raises(ImportError) as e:
        read_measured(tmp_path / "x.uff", nodes=NODES)
    one_line(e, 'pip install ".[uff]" in the clone')
    with pytest.raises(ImportError):
        export_uff58(tmp_path / "x.uff", FREQ, np.ones((FREQ.size, 2)), force_n=1.0)


# ---------------------------------------------------------------- CSV

CSV = """# rig run 12, beams 1-3, accelerometer amplitudes converted to m
frequency_hz,beam1,beam2,beam3,force_n,kind
30,1e-5,2e-5,3e-5,0.25,stepped
40,1.5e-5,,3.5e-5,0.25,stepped
50,2e-5,2.5e-5,4e-5,0.25,stepped
30,1.1e-5,2.1e-5,3.1e-5,0.50,stepped
20,1e-6,1e-6,1e-6,0.25,sweep
25,2e-6,2e-6,2e-6,0.25,sweep
"""


def test_csv_groups_by_kind_and_force(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text(CSV)
    ms = read_measured(path)
    assert [(m.kind, m.force_n, m.frequency_hz.size) for m in ms] == [
        ("stepped", 0.25, 3), ("stepped", 0.5, 1), ("sweep", 0.25, 2)]
    m = ms[0]
    assert m.beams == (1, 2, 3) and m.quantity == "displacement" and not m.is_complex
    assert np.isnan(m.response[1, 1]) and m.n_points == 8
    np.testing.assert_array_equal(m.column(3), [3e-5, 3.5e-5, 4e-5])
    # the metric needs every beam: NaN where beam 2 is missing
    np.testing.assert_array_equal(m.metric().response[:, 0], [3e-5, np.nan, 4e-5])


def test_csv_complex_velocity_and_defaults(tmp_path):
    f = np.array([10.0, 20.0])
    V = np.array([1e-3 + 2e-3j, -3e-3j])
    path = tmp_path / "v.csv"
    path.write_text("frequency_hz,re_beam2,im_beam2\n" +
                    "".join(f"{a},{v.real},{v.imag}\n" for a, v in zip(f, V)))
    (m,) = read_measured(path, quantity="velocity", force_n=0.3)
    assert m.beams == (2,) and m.kind == "stepped" and m.force_n == 0.3 and m.is_complex
    np.testing.assert_allclose(m.displacement().response[:, 0], V / (2j * np.pi * f))
    np.testing.assert_allclose(m.displacement().amplitude[:, 0], np.abs(V) / (2 * np.pi * f))
    with pytest.raises(ValueError) as e:
        normalise(read_measured(path, quantity="velocity")[0], 0.22)
    one_line(e, str(path), "force level unknown")


@pytest.mark.parametrize("text, words", [
    ("beam1,beam2\n1e-5,2e-5\n", ["missing column", "frequency_hz"]),
    ("frequency_hz,force_n\n10,0.2\n", ["missing column", "beam<k>"]),
    ("frequency_hz,re_beam1\n10,1e-5\n", ["missing column", "im_beam1"]),
    ("frequency_hz,beam1,temp\n10,1e-5,20\n", ["unknown column", "temp"]),
    ("frequency_hz,beam1,re_beam2,im_beam2\n10,1,1,1\n", ["mix of amplitude"]),
    ("frequency_hz,beam1\n10,-1e-5\n", ["line 2", "amplitudes must be >= 0"]),
    ("frequency_hz,beam1\n10,1e-5,3\n", ["line 2", "3 fields"]),
    ("frequency_hz,beam1\n0,1e-5\n", ["line 2", "frequency_hz must be > 0"]),
    ("frequency_hz,beam1\n10,abc\n", ["line 2", "beam1", "not a number"]),
    ("frequency_hz,beam1,kind\n10,1e-5,swept\n", ["line 2", "kind 'swept'"]),
    ("frequency_hz,beam1\n", ["no data rows"]),
])
def test_bad_csv_files(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as e:
        read_measured(path)
    one_line(e, str(path), *words)


@pytest.mark.parametrize("kw, words", [
    # float() took "2" and True as numbers; "x" failed with Python's words, naming nothing
    (dict(scale="2"), "scale: expected a number > 0"),
    (dict(scale=True), "scale: expected a number > 0"),
    (dict(force_n="1"), "force_n: expected a force > 0 N"),
    (dict(force_n="x"), "force_n: expected a force > 0 N"),
])
def test_arguments_that_are_not_numbers_are_named(tmp_path, kw, words):
    path = tmp_path / "m.csv"
    path.write_text("frequency_hz,beam1\n10,1e-5\n")
    with pytest.raises(ValueError) as e:
        read_measured(path, **kw)
    one_line(e, str(path), words)


# ---------------------------------------------------------------- fraction inside

def test_log_linear_interpolation_is_exact_for_exponentials():
    g = np.array([10.0, 20.0, 40.0, 41.0])
    v = np.exp(-0.1 * g)[:, None] * [1.0, 3.0]
    at = np.array([10.0, 12.5, 33.3, 40.0, 40.5, 41.0])
    np.testing.assert_allclose(interpolate_log(g, v, at), np.exp(-0.1 * at)[:, None] *
                               [1.0, 3.0], rtol=1e-13)
    # grid frequencies give the grid values exactly; a zero end gives 0; NaN propagates
    np.testing.assert_array_equal(interpolate_log(g, v, g), v)
    z = np.array([1.0, 0.0, 2.0, np.nan])
    np.testing.assert_array_equal(interpolate_log(g, z, np.array([15.0, 30.0, 40.0, 40.5])),
                                  [0.0, 0.0, 2.0, np.nan])


def test_fraction_inside_counts():
    g = np.array([10.0, 20.0, 30.0])
    lo = np.array([1.0, 2.0, 4.0])
    up = 10 * lo
    mid = math.sqrt(2.0 * 4.0)          # log-linear value of lo at 25 Hz: sqrt(2*4)
    f = np.array([5.0, 10.0, 25.0, 25.0, 25.0, 30.0, 35.0])
    a = np.array([[0.1, 1.0, mid * 0.999, mid * 1.000001, 10 * mid * 1.001, 40.0, 1.0],
                  [np.nan, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0]]).T
    m = Measurement(f, a, beams=(3, 4))
    r = fraction_inside(m, g, lo, up)
    assert r.beams == (3, 4)
    assert (r.inside[3], r.below[3], r.above[3]) == (3, 1, 1)
    assert r.outside_range == {3: 2, 4: 1} and r.missing == {3: 0, 4: 1}
    assert r.fraction(3) == 3 / 5 and r.fraction(4) == 1.0
    assert r.overall == 8 / 10 and r.compared() == 10
    assert "80.0 %" in r.text() and "3 outside the bounds' frequency range" in r.text()
    # one beam only; per-beam bound columns (column b - 1 for beam b)
    assert fraction_inside(m, g, lo, up, beams=[4]).per_beam == {4: 1.0}
    lo2 = np.column_stack([lo] * 4)
    lo2[:, 3] = 6.0
    r2 = fraction_inside(m, g, lo2, np.column_stack([up] * 4))
    assert r2.fraction(4) == 0.0 and r2.fraction(3) == 3 / 5
    r3 = fraction_inside(m, g, lo2, np.column_stack([up] * 4), check_lower=False)
    assert r3.fraction(4) == 1.0 and r3.fraction(3) == 4 / 5 and r3.below == {3: 0, 4: 0}
    # pooled measurements; bounds in acceleration compare converted data
    assert fraction_inside([m, m], g, lo, up).compared() == 20
    acc = fraction_inside(m, g, lo * 1e6, up * 1e6, quantity="acceleration")
    assert acc.compared() == 10


def test_fraction_inside_bad_input():
    m = Measurement([10.0], [[1.0]], beams=(1,))
    with pytest.raises(ValueError, match="strictly increasing"):
        fraction_inside(m, [20.0, 10.0], [1, 1], [2, 2])
    with pytest.raises(ValueError, match="expected shape"):
        fraction_inside(m, [10.0, 20.0], [1, 1, 1], [2, 2, 2])
    with pytest.raises(ValueError, match="no bound column for beam 1"):
        fraction_inside(m, [10.0, 20.0], np.ones((2, 0)), np.ones((2, 0)))
    with pytest.raises(ValueError, match="beam 2 is not in the measurement"):
        fraction_inside(m, [10.0, 20.0], [1, 1], [2, 2], beams=[2])
    # a NaN or negative tolerance counted every point inside, or each twice
    for rtol in (np.nan, -2.0, 0.7):
        with pytest.raises(ValueError, match="rtol"):
            fraction_inside(m, [10.0, 20.0], [1, 1], [2, 2], rtol=rtol)
    with pytest.raises(ValueError, match="lower above upper"):
        fraction_inside(m, [10.0, 20.0], [2, 1], [1, 2])
    with pytest.raises(ValueError, match="lower: expected real"):
        fraction_inside(m, [10.0, 20.0], [1j, 1], [2, 2])


def test_measurement_validation():
    with pytest.raises(ValueError, match="amplitudes must be >= 0"):
        Measurement([10.0], [[-1.0]], beams=(1,))
    # inf in one part of a complex value with NaN in the other passed as "not measured"
    # and counted as a point above the bounds
    for bad in (complex(np.inf, np.nan), complex(np.nan, -np.inf), complex(np.inf, 0.0)):
        with pytest.raises(ValueError, match="values must be finite"):
            Measurement([10.0], [[bad]], beams=(1,))
    for missing in (complex(np.nan, np.nan), complex(np.nan, 0.0)):
        assert np.isnan(Measurement([10.0], [[missing]], beams=(1,)).amplitude)
    with pytest.raises(ValueError, match="one per column"):
        Measurement([10.0], [[1.0, 2.0]], beams=(1,))
    with pytest.raises(ValueError, match="kind"):
        Measurement([10.0], [[1.0]], beams=(1,), kind="chirp")
    with pytest.raises(ValueError, match="> 0 Hz"):
        Measurement([0.0], [[1.0]], beams=(1,))
    # truncated or parsed before: 1.7 was beam 1, "1" beam 1
    for beams in ((1.7,), "1", (True,)):
        with pytest.raises(ValueError, match="beams: expected integer"):
            Measurement([10.0], [[1.0]], beams=beams)
    for p in (500.0, np.nan):
        with pytest.raises(ValueError, match="percentile"):
            Measurement([10.0], [[1.0]], beams=(1,), percentile=p)
    m = Measurement([10.0], [[1.0]], beams=(1,), force_n=0.2)
    for F0 in ("1", True, None):            # float() took the first two
        with pytest.raises(ValueError, match="F0"):
            normalise(m, F0)
    with pytest.raises(ValueError, match="increasing"):
        interpolate_log([2.0, 1.0], np.ones(2), np.array([1.5]))


@pytest.mark.filterwarnings("ignore::ResourceWarning",
                            "ignore::pytest.PytestUnraisableExceptionWarning")
def test_binary_58b_records(tmp_path):
    # 58b: the closing delimiter follows the binary data directly
    f = np.linspace(10.0, 50.0, 200)
    y = 1e-5 * np.exp(1j * f / 7)
    recs = [record(n, f, y * (j + 1), func_type=0, spec=8, denom=0,
                   ids={"binary": 1, "abscissa_spacing": 1}) for j, n in enumerate(NODES)]
    path = tmp_path / "bin.uff"
    # pyuff's overwrite mode truncates binary headers: add to a new file instead
    pyuff.UFF(str(path)).write_sets(recs, mode="add")
    gc.collect()  # pyuff's binary writer leaks file handles: close them here
    (m,) = read_measured(path, nodes=NODES)
    np.testing.assert_array_equal(m.response[:, 1], 2 * y)
    np.testing.assert_allclose(m.frequency_hz, f, atol=1e-5)
    raw = path.read_bytes()
    bad = tmp_path / "bin_cut.uff"
    bad.write_bytes(raw[:-40])
    with pytest.raises(ValueError) as e:
        read_measured(bad, nodes=NODES)
    one_line(e, str(bad), "truncated")


@pytest.mark.parametrize("path", [3, None, ["x.uff"]])
def test_a_path_of_another_type_is_named(path):
    # Path() raised a TypeError that named no argument
    with pytest.raises(ValueError, match="^path: expected a UFF or CSV file's path, got"):
        read_measured(path, nodes=NODES)
