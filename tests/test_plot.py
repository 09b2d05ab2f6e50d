"""`mcfric plot`: the figure of a results file (not blank: bounds, cloud), PDF output, the
quantity and frequency-window options, bad inputs, and a measured overlay made from a
member of the run itself (100 % inside)."""

import csv
import re

import h5py
import numpy as np
import pytest
from matplotlib.image import imread

from mcfric import cli
from mcfric.validators import InputError

TAB_BLUE = (31 / 255, 119 / 255, 180 / 255)     # upper bound
TAB_RED = (214 / 255, 39 / 255, 40 / 255)       # lower bound
TAB_GREEN = (44 / 255, 160 / 255, 44 / 255)     # measured data
TAB_PURPLE = (148 / 255, 103 / 255, 189 / 255)  # member peaks left at grid values


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """A small two-beam results file with its bounds (20 members x 60 frequencies)."""
    path = tmp_path_factory.mktemp("plot") / "x.h5"
    rc = cli.main(["run", "two-beam", "--samples", "20", "--n-freq", "60", "-o", str(path),
                   "--no-progress", "--no-figure"])
    assert rc == 0 and path.is_file()
    return path


def call(argv, capsys):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def rgb(png):
    img = imread(png)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    return img[..., :3].astype(float)


def near(img, colour, tol=0.08):
    """Pixels within ``tol`` of ``colour`` in every channel."""
    return int(np.count_nonzero(np.abs(img - np.asarray(colour)).max(axis=-1) < tol))


def assert_not_blank(img):
    non_white = np.any(img < 0.98, axis=-1).mean()
    assert non_white > 0.10, f"only {100 * non_white:.1f} % of the pixels are not white"
    q = np.round(img * 15).astype(int)                          # 4 bits per channel
    _, counts = np.unique(q[..., 0] * 256 + q[..., 1] * 16 + q[..., 2], return_counts=True)
    assert np.count_nonzero(counts >= 50) >= 8, "too few distinct colours"


def test_png_shows_bounds_and_cloud(results, tmp_path, capsys):
    png = tmp_path / "fig.png"
    rc, out, err = call(["plot", results, "-o", png], capsys)
    assert rc == 0, err
    # (on this 60-point grid a member may keep an unrefined low maximum that a narrow
    # resonance could lie behind: the line then says so after "bounds")
    assert f"figure: {png} (20 of 20 members drawn, bounds" in out
    img = rgb(png)
    assert_not_blank(img)
    assert near(img, TAB_BLUE) > 1000, "no upper bound (blue) drawn"
    assert near(img, TAB_RED) > 1000, "no lower bound (red) drawn"
    # the cloud: light, unsaturated grey (grey lines at low alpha, over white or the pale
    # blue band); a figure of the bounds alone has ~2000 such pixels (text antialiasing),
    # this one ~20000
    mean, spread = img.mean(axis=-1), np.ptp(img, axis=-1)
    grey = np.count_nonzero((spread < 0.07) & (mean > 0.70) & (mean < 0.86))
    assert grey > 8000, f"no ensemble cloud (grey): {grey} pixels"


def test_pdf_output(results, tmp_path, capsys):
    pdf = tmp_path / "fig.pdf"
    rc, out, err = call(["plot", results, "-o", pdf], capsys)
    assert rc == 0, err
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF") and len(data) > 5000


def test_quantity_and_window(results, tmp_path, capsys):
    base, acc, win = tmp_path / "d.png", tmp_path / "a.png", tmp_path / "w.png"
    assert call(["plot", results, "-o", base], capsys)[0] == 0
    rc, _, err = call(["plot", results, "-o", acc, "--quantity", "acceleration"], capsys)
    assert rc == 0, err
    rc, _, err = call(["plot", results, "-o", win, "--f-min", "30", "--f-max", "80"], capsys)
    assert rc == 0, err
    imgs = {p.name: rgb(p) for p in (base, acc, win)}
    for name, img in imgs.items():
        assert_not_blank(img)
        assert near(img, TAB_BLUE) > 500 and near(img, TAB_RED) > 500, name
    assert imgs["a.png"].shape != imgs["d.png"].shape or not np.array_equal(imgs["a.png"],
                                                                              imgs["d.png"])
    assert imgs["w.png"].shape != imgs["d.png"].shape or not np.array_equal(imgs["w.png"],
                                                                              imgs["d.png"])


@pytest.mark.parametrize("case", ["missing file", "jpg output", "f-min above f-max",
                                  "window outside the grid", "bad quantity", "infinite f-max",
                                  "NaN f-min", "negative f-min", "a directory"])
def test_bad_input_is_one_line_exit_2(case, results, tmp_path, capsys):
    out_png = tmp_path / "fig.png"
    argv = {
        "missing file": ["plot", tmp_path / "nope.h5", "-o", out_png],
        "jpg output": ["plot", results, "-o", tmp_path / "fig.jpg"],
        "f-min above f-max": ["plot", results, "-o", out_png, "--f-min", "100",
                              "--f-max", "50"],
        "window outside the grid": ["plot", results, "-o", out_png, "--f-min", "200",
                                    "--f-max", "300"],
        "bad quantity": ["plot", results, "-o", out_png, "--quantity", "force"],
        "infinite f-max": ["plot", results, "-o", out_png, "--f-max", "inf"],
        "NaN f-min": ["plot", results, "-o", out_png, "--f-min", "nan"],
        "negative f-min": ["plot", results, "-o", out_png, "--f-min", "-1"],
        "a directory": ["plot", tmp_path, "-o", out_png],
    }[case]
    words = {"f-min above f-max": "--f-min: expected f-min < f-max",
             "infinite f-max": "--f-max: expected a frequency",
             "NaN f-min": "--f-min: expected a frequency",
             "negative f-min": "--f-min: expected a frequency >= 0 Hz, got -1",
             "a directory": "a directory, not a results file",
             "window outside the grid": "--f-min/--f-max: no frequencies of"}.get(case, "")
    rc, out, err = call(argv, capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mcfric: error: ") and words in err, err
    assert not out_png.exists() and not (tmp_path / "fig.jpg").exists()


def test_a_window_beyond_the_grid_spans_the_grid(results, tmp_path):
    """--f-min 0 --f-max 1e308 is every frequency: the axis spans the file's frequencies
    (matplotlib warned of an overflow drawing 1e308 Hz; warnings are errors here)."""
    from mcfric import plot

    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
    drawn = plot.results_figure(results, tmp_path / "w.png", f_window=(0.0, 1e308))
    lo, hi = drawn["xlim"]
    assert f.min() - 0.01 * np.ptp(f) < lo < f.min() and f.max() < hi < f.max() + 0.01 * np.ptp(f)
    with pytest.raises(InputError, match="expected 0 <= f_min < f_max"):
        plot.results_figure(results, tmp_path / "n.png", f_window=(-1.0, 50.0))


def _member_csv(results, path, member, scale=1.0):
    """CSV of one member's |response| per beam (frequency_hz, beam1, beam2, kind)."""
    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
        y = np.abs(h5["response"][member]) * scale               # (frequency, beam)
        assert np.all(h5["converged"][member])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "beam1", "beam2", "kind"])
        for fi, row in zip(f, y):
            w.writerow([repr(float(fi)), repr(float(row[0])), repr(float(row[1])), "sweep"])
    return len(f)


def _fractions(out):
    """(percent, inside, compared) of each 'inside the bounds' line printed."""
    return [(float(p), int(a), int(b)) for p, a, b in
            re.findall(r"measured points inside the bounds: ([\d.]+) % \((\d+)/(\d+)\)", out)]


def test_measured_member_is_inside(results, tmp_path, capsys):
    data = tmp_path / "member.csv"
    n_f = _member_csv(results, data, member=3)
    png = tmp_path / "m.png"
    rc, out, err = call(["plot", results, "-o", png, "--measured", data], capsys)
    assert rc == 0, err
    # per beam against the upper bound (2 beams), the measured metric against both bounds
    assert _fractions(out) == [(100.0, 2 * n_f, 2 * n_f), (100.0, n_f, n_f)], out
    assert near(rgb(png), TAB_GREEN) > 300, "measured sweep (green) not drawn"
    # the CSV has no force_n column: taken to be at the file's F0, and said so
    assert f"note: {data} gives no force level: compared as if measured at F0 = 0.22 N" in out


def test_beams_measured_at_different_frequencies_are_compared_per_point(results, tmp_path,
                                                                         capsys, monkeypatch):
    """A member's beams measured at alternate frequencies, both at every fifth (records
    merged onto the union of the frequencies): M is measured at those points only, the
    largest measured beam elsewhere. Both are compared and drawn, each line broken where
    its points stop and named for what it is (before, M was NaN at every point where a
    beam was missing: nothing compared, nothing drawn)."""
    from mcfric import plot
    from mcfric.measured import read_measured

    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
        y = np.abs(h5["response"][3])
    n_f = len(f)
    both = np.arange(n_f) % 5 == 0
    n_both = int(np.count_nonzero(both))
    data = tmp_path / "merged.csv"
    with open(data, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "beam1", "beam2", "kind"])
        for k, (fi, row) in enumerate(zip(f, y)):
            w.writerow([repr(float(fi)), repr(float(row[0])) if both[k] or k % 2 == 0 else "",
                        repr(float(row[1])) if both[k] or k % 2 == 1 else "", "sweep"])
    png = tmp_path / "m.png"
    rc, out, err = call(["plot", results, "-o", png, "--measured", data], capsys)
    assert rc == 0, err
    # beams: every value against the upper bound; M at the shared points; the largest
    # beam at the others against the upper bound only
    assert _fractions(out) == [(100.0, n_f + n_both, n_f + n_both), (100.0, n_both, n_both),
                               (100.0, n_f - n_both, n_f - n_both)], out
    assert "the measured metric M (max over the beams) against both bounds" in out
    assert "where not every beam of the metric (1, 2) is measured" in out
    assert near(rgb(png), TAB_GREEN) > 100, "measured data (green) not drawn"
    saved = []
    monkeypatch.setattr(plot, "_save", lambda fig, out, dpi: saved.append(fig))
    plot.results_figure(results, tmp_path / "n.png", measured=read_measured(data))
    lines = {ln.get_label(): ln for ln in saved[-1].axes[0].get_lines()}
    m_line = lines["measured sweep merged.csv"]
    part = lines["measured sweep merged.csv: points where not every beam is measured, M at "
                 "least this"]
    ym, yp = np.asarray(m_line.get_ydata(), float), np.asarray(part.get_ydata(), float)
    assert np.array_equal(np.isfinite(ym), both) and np.array_equal(np.isfinite(yp), ~both)
    np.testing.assert_allclose(ym[both], y[both].max(axis=1), rtol=1e-12)


def test_measured_outside_is_counted(results, tmp_path, capsys):
    data = tmp_path / "loud.csv"
    n_f = _member_csv(results, data, member=3, scale=100.0)     # far above the upper bound
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data],
                        capsys)
    assert rc == 0, err
    fr = _fractions(out)
    assert len(fr) == 2 and fr[1][2] == n_f
    assert all(p < 100.0 for p, _, _ in fr), out


def test_a_measured_amplitude_near_the_float_limit_is_drawn_on_the_axis(results, tmp_path,
                                                                          monkeypatch):
    """A measured 1e308 m (and a subnormal 1e-320 m): matplotlib's log margin overflowed (a numpy
    warning), the axis ran from 1 to 10 and showed nothing. Now no warning, and the axis
    holds every measured point and the bounds."""
    import warnings

    from mcfric import plot
    from mcfric.measured import read_measured

    data = tmp_path / "huge.csv"
    data.write_text("frequency_hz,beam1,beam2\n30,1e308,1e-5\n40,1e-320,1e-320\n")
    saved = []
    monkeypatch.setattr(plot, "_save", lambda fig, out, dpi: saved.append(fig) or
                        fig.savefig(tmp_path / "huge.png", dpi=dpi))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plot.results_figure(results, tmp_path / "x.png",
                            measured=read_measured(data, force_n=0.22))
    bottom, top = saved[-1].axes[0].get_ylim()
    assert 0 < bottom <= 1e-320 and top >= 1e308 and np.isfinite(top)
    assert (tmp_path / "huge.png").stat().st_size > 10_000


def test_measured_points_are_judged_against_the_certified_band(results, tmp_path, capsys):
    """Where the searched (paper's) upper bound lies above the certified one, a point
    between them is outside the band the figure draws: it counts as outside."""
    from mcfric.bounds import read_bounds

    B = read_bounds(results)
    C = B.certificate
    k = np.flatnonzero(C.upper < 0.995 * B.upper)
    assert k.size >= 2
    v = np.sqrt(C.upper[k] * B.upper[k])                 # above certified, below searched
    data = tmp_path / "between.csv"
    with open(data, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "beam1", "beam2", "kind"])
        for fi, vi in zip(B.freq_hz[k], v):
            w.writerow([repr(float(fi)), repr(float(vi)), repr(float(vi)), "stepped"])
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data],
                        capsys)
    assert rc == 0, err
    assert "against the certified bounds" in out
    assert _fractions(out)[1] == (0.0, 0, k.size), out      # was 100 % (the searched bounds)


def _beam2_csv(results, path, member, scale=1.0, force_n=None, freqs=None):
    """CSV of beam 2's |response| only (optionally with a force_n column), at the grid
    frequencies or at ``freqs`` (interpolated in log amplitude)."""
    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
        y = np.abs(h5["response"][member][:, 1]) * scale
    if freqs is not None:
        y, f = np.exp(np.interp(freqs, f, np.log(y))), np.asarray(freqs)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "beam2", "kind"] + (["force_n"] if force_n else []))
        for fi, yi in zip(f, y):
            w.writerow([repr(float(fi)), repr(float(yi)), "sweep"]
                       + ([repr(force_n)] if force_n else []))
    return len(f)


def test_a_measured_subset_of_the_beams_is_held_to_the_upper_bound_only(results, tmp_path,
                                                                       capsys):
    """Beam 2 alone (the metric is over beams 1 and 2): its maximum is no measured M and
    may lie below the lower bound of M; it counted as outside there before."""
    data = tmp_path / "b2.csv"
    n_f = _beam2_csv(results, data, member=3, scale=0.3)
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data],
                        capsys)
    assert rc == 0, err
    assert "where not every beam of the metric (1, 2) is measured: M could be larger" in out, out
    assert "against both bounds" not in out
    assert _fractions(out) == [(100.0, n_f, n_f), (100.0, n_f, n_f)], out
    # the figure says the same: drawn as M it dipped below the lower bound unexplained
    from mcfric import measured, plot
    drawn = plot.results_figure(results, tmp_path / "n.png",
                                measured=measured.read_measured(data, force_n=0.22))
    assert "measured sweep b2.csv (0.22 N): beam 2 only, M at least this" in drawn["legend"]


def test_measured_data_at_another_force_needs_normalise(results, tmp_path, capsys):
    data = tmp_path / "loud.csv"
    _beam2_csv(results, data, member=3, force_n=0.44)
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data],
                        capsys)
    assert rc == 2 and "measured at 0.44 N, the file is for F0 = 0.22 N" in err, err
    assert not (tmp_path / "m.png").exists()
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data,
                         "--normalise"], capsys)
    assert rc == 0 and out.count("normalised to F0 = 0.22 N") == 1, (out, err)


def test_points_outside_between_grid_frequencies_are_named(results, tmp_path, capsys):
    """The bounds hold at their grid; between grid frequencies they are interpolated,
    which is not a bound: outside points there are counted apart, and the header says
    how far apart the grid frequencies are."""
    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
    mid = 0.5 * (f[:-1] + f[1:])
    on = np.round(f[1:-1], 4)                # on the grid, as a file prints them
    data = tmp_path / "mid.csv"
    n = _beam2_csv(results, data, member=3, scale=100.0,
                   freqs=np.sort(np.r_[mid, on]))                     # all above
    assert n == mid.size + on.size
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data],
                        capsys)
    assert rc == 0, err
    assert "hold at the 60 grid frequencies" in out and "interpolated between them" in out
    # every point is outside; only those between grid frequencies are named so
    assert f"{mid.size} of the points outside lie between grid frequencies" in out, out
    assert _fractions(out)[0] == (0.0, 0, n), out


def test_the_measured_force_can_be_given_on_the_command_line(results, tmp_path, capsys):
    """A file without a force level takes --measured-force (UFF FRFs need one); it is
    then held to the file's F0 like a force given in the file."""
    data = tmp_path / "b2.csv"
    _beam2_csv(results, data, member=3)
    png = tmp_path / "m.png"
    rc, _, err = call(["plot", results, "-o", png, "--measured", data, "--measured-force",
                       "0.44"], capsys)
    assert rc == 2 and "measured at 0.44 N" in err, err
    rc, out, err = call(["plot", results, "-o", png, "--measured", data, "--measured-force",
                         "0.44", "--normalise"], capsys)
    assert rc == 0 and "c = F0/F_meas = 0.22/0.44" in out, err
    # a force level so small that the factor overflows: one line, no figure
    rc, out, err = call(["plot", results, "-o", tmp_path / "t.png", "--measured", data,
                         "--measured-force", "1e-310", "--normalise"], capsys)
    assert rc == 2 and "puts the response out of range" in err and err.count("\n") == 1, err
    assert not (tmp_path / "t.png").exists()


def test_a_triaxial_uff_file_takes_the_measured_direction(results, tmp_path, capsys):
    """X records far above the bounds, Z records of a member: without a direction the
    file is refused (two records per node); --measured-direction picks one."""
    pytest.importorskip("pyuff")
    from mcfric.measured import export_uff58

    with h5py.File(results, "r") as h5:
        f, y = h5["frequency"][()], np.abs(h5["response"][3])
    parts = []
    for d, scale in ((1, 100.0), (3, 1.0)):
        export_uff58(tmp_path / f"d{d}.uff", f, y * scale, force_n=0.22, nodes=[102, 202],
                     direction=d)
        parts.append((tmp_path / f"d{d}.uff").read_text())
    tri = tmp_path / "tri.uff"
    tri.write_text("".join(parts))
    base = ["plot", results, "-o", tmp_path / "m.png", "--measured", tri, "--nodes",
            "102,202"]
    rc, _, err = call(base, capsys)
    assert rc == 2 and "--measured-direction" in err, err
    # without --nodes: the flag to give, not the API's nodes= (the file's nodes named)
    rc, _, err = call(base[:-2] + ["--measured-direction", "3"], capsys)
    assert rc == 2 and "give --nodes N1,N2,..." in err and "102" in err, err
    assert "nodes=" not in err and err.count("\n") == 1
    rc, out, err = call(base + ["--measured-direction", "3"], capsys)
    assert rc == 0 and all(p == 100.0 for p, _, _ in _fractions(out)), out
    rc, out, err = call(base + ["--measured-direction", "1"], capsys)
    assert rc == 0 and all(p < 100.0 for p, _, _ in _fractions(out)), out


def test_exported_percentiles_of_m_read_back_as_the_metric(results, tmp_path, capsys):
    """An exported M record (node 900) maps to beam 0, the metric, with --nodes 900:0 and
    is held to both bounds; it was read as beam 1."""
    pytest.importorskip("pyuff")
    from mcfric.measured import export_uff58

    with h5py.File(results, "r") as h5:
        f, m = h5["frequency"][()], h5["metric"][()]
    pct = export_uff58(tmp_path / "p.uff", f, np.percentile(m, [5, 50, 95], axis=0),
                       percentiles=[5, 50, 95], force_n=0.22, nodes=[900])
    assert pct["records"] == 3
    rc, out, err = call(["plot", results, "-o", tmp_path / "p.png", "--measured",
                         tmp_path / "p.uff", "--nodes", "900:0"], capsys)
    assert rc == 0, err
    assert "the measured metric M (max over the beams) against both bounds" in out, out
    assert _fractions(out) == [(100.0, 3 * f.size, 3 * f.size)], out    # on the grid


def test_a_window_compares_exactly_its_measured_points(results, tmp_path, capsys):
    """--f-min/--f-max: every measured point in the window is compared (one near the
    edge, beyond the last grid frequency inside it, was excluded), the others are
    counted apart."""
    with h5py.File(results, "r") as h5:
        f = h5["frequency"][()]
    pts = np.r_[np.linspace(12.0, 39.9, 30), 39.99, np.linspace(41.0, 140.0, 20)]
    data = tmp_path / "w.csv"
    _beam2_csv(results, data, member=3, freqs=pts)
    assert f[f <= 40.0].max() < 39.9                  # the edge point lies past the grid
    rc, out, err = call(["plot", results, "-o", tmp_path / "w.png", "--measured", data,
                         "--f-min", "20", "--f-max", "40"], capsys)
    assert rc == 0, err
    inside = int(np.count_nonzero((pts >= 20) & (pts <= 40)))
    assert f"{pts.size - inside} measured points outside 20-40 Hz (not compared)" in out, out
    assert _fractions(out)[0][2] == inside, out


def test_measured_options_that_cannot_apply_are_refused_or_said(results, tmp_path, capsys):
    data = tmp_path / "b2.csv"
    _beam2_csv(results, data, member=3)
    for argv, message in ((["--normalise"], "--normalise: applies to --measured data"),
                          (["--measured-force", "0"],
                           "--measured-force: applies to --measured data"),
                          (["--measured", data, "--nodes", "1,2"], "--nodes: maps UFF"),
                          (["--measured", data, "--measured-force", "-1"],
                           "--measured-force: expected a force > 0 N")):
        rc, _, err = call(["plot", results, "-o", tmp_path / "m.png", *argv], capsys)
        assert rc == 2 and message in err, err
    rc, out, err = call(["plot", results, "-o", tmp_path / "m.png", "--measured", data, data,
                         "--normalise", "--measured-force", "0.44"], capsys)
    assert rc == 2 and "given twice" in err and out == "", (out, err)
    nb = tmp_path / "nb.h5"
    assert cli.main(["run", "two-beam", "--samples", "2", "--n-freq", "10", "--no-bounds",
                     "--no-progress", "--no-figure", "-o", str(nb)]) == 0
    capsys.readouterr()
    rc, out, err = call(["plot", nb, "-o", tmp_path / "n.png", "--measured", data], capsys)
    assert rc == 0 and "not compared (the file has no bounds)" in out, out
    bf = tmp_path / "b.h5"
    assert cli.main(["bounds", "two-beam", "--n-freq", "10", "--no-certify", "--no-figure",
                     "-o", str(bf)]) == 0
    capsys.readouterr()
    rc, _, err = call(["plot", bf, "-o", tmp_path / "b.png", "--member", "3"], capsys)
    assert rc == 2 and "holds no members" in err, err
    rc, out, _ = call(["plot", bf, "-o", tmp_path / "b.png"], capsys)   # was "0 of 0 members"
    assert rc == 0 and out == f"figure: {tmp_path / 'b.png'} (bounds only)\n", out
    part = tmp_path / "p.h5"
    part.with_name("p.h5.partial").write_bytes(b"")
    rc, _, err = call(["plot", part, "-o", tmp_path / "p.png"], capsys)
    assert rc == 2 and "the run is not complete" in err, err


def test_failed_points_and_unrefined_peaks_are_shown_as_such(tmp_path, capsys):
    """One Newton iteration per attempt (mu0 = 0.1, kc = 6 kN/m on every damper): some
    points fail and some peaks stay grid values. The figure says how many points are
    gaps and draws the unrefined peaks apart (purple circles), and `mcfric plot` prints
    both counts."""
    from mcfric import config, ensemble, plot

    cfg = config.load({"model": {"preset": "eight-beam"}, "frequency": {"n": 20},
                       "sampling": {"samples": 30, "mu0": {"dist": "fixed", "value": 0.1},
                                    "kc": {"dist": "fixed", "value": 6000.0}},
                       "solver": {"max_iter": 1}, "bounds": {"enabled": False}})
    path = ensemble.run(cfg, tmp_path / "t.h5", progress=False, groups=None).path
    with h5py.File(path, "r") as h5:
        failed = int(np.count_nonzero(~h5["converged"][()]))
        grid = int(np.count_nonzero((h5["peak_status"][()] == 2)
                                    & np.isfinite(h5["peak_metric"][()])))
    assert failed > 0 and grid > 0
    drawn = plot.results_figure(path, tmp_path / "t.png", indicator=False)
    assert drawn["n_not_converged"] == failed
    assert drawn["n_peaks_unrefined"] <= grid and drawn["n_peaks_unrefined"] > 0
    assert near(rgb(tmp_path / "t.png"), TAB_PURPLE) > 20, "unrefined peaks not drawn"
    rc, out, err = call(["plot", path, "-o", tmp_path / "u.png"], capsys)
    assert rc == 0, err
    assert f"{failed:,} points not converged, left as gaps" in out
    assert "member peaks not refined, drawn as circles" in out


def test_member_out_of_range_is_refused(results, tmp_path, capsys):
    from mcfric import cli

    rc = cli.main(["plot", str(results), "-o", str(tmp_path / "m.png"), "--member", "999"])
    err = capsys.readouterr().err
    assert rc == 2 and "--member" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.png").exists()


def test_python_ensemble_run_stores_bounds_by_default(tmp_path):
    """ensemble.run from Python writes bounds/ as the CLI does ([bounds] enabled)."""
    from mcfric import config, ensemble
    from mcfric.bounds import read_bounds

    cfg = config.load("two-beam", {"sampling.samples": (8, "--samples"),
                                   "frequency.n": (30, "--n-freq")})
    ensemble.run(cfg, tmp_path / "r.h5", progress=False)
    B = read_bounds(tmp_path / "r.h5")
    assert B is not None and B.n_failed == 0 and len(B.upper) == 30
    off = cfg.replace("bounds.enabled", False)
    ensemble.run(off, tmp_path / "n.h5", progress=False)
    assert read_bounds(tmp_path / "n.h5") is None


def test_the_cloud_draws_at_most_max_lines_and_the_envelope_of_all(tmp_path):
    """1000 members, ``max_lines = 400``: exactly 400 drawn (500 before: a step of 2),
    the envelope of all 1000 drawn and named; the peaks are every member's."""
    from mcfric import config, ensemble, plot
    cfg = config.load({"model": {"preset": "two-beam"}, "frequency": {"n": 100},
                       "sampling": {"samples": 1000}, "bounds": {"enabled": False}})
    path = ensemble.run(cfg, tmp_path / "b.h5", progress=False).path
    drawn = plot.results_figure(path, tmp_path / "b.png", max_lines=400, indicator=False)
    assert drawn["n_drawn"] == 400
    assert "envelope of all 1,000 members" in drawn["legend"]
    assert any(t.startswith("refined member peaks (every member") for t in drawn["legend"])
    # peaks refined as displacements, drawn as accelerations: said to be lower estimates
    acc = plot.results_figure(path, tmp_path / "a.png", quantity="acceleration",
                              max_lines=10, indicator=False)
    assert any(t.startswith("refined member peaks (every member; refined as displacement, "
                            "converted: may lie slightly low") for t in acc["legend"])
    for n, k in ((1000, 400), (799, 400), (10, 400), (7, 3), (1, 1)):
        assert np.count_nonzero(plot._drawn(np.arange(n), n, k)) == min(n, k)
    with pytest.raises(ValueError, match="member: expected None or a member in 0..999"):
        plot.results_figure(path, tmp_path / "c.png", member=1000)
    with pytest.raises(ValueError, match="max_lines: expected an integer >= 1"):
        plot.results_figure(path, tmp_path / "c.png", max_lines=0)
    with pytest.raises(ValueError, match="indicator: expected True or False, got 'no'"):
        plot.results_figure(path, tmp_path / "c.png", indicator="no")
    assert not (tmp_path / "c.png").exists()


def test_folds_are_drawn_and_their_lower_estimates_marked(results, tmp_path, capsys,
                                                          monkeypatch):
    """The plot drew the upward peaks only: a fold's branch from above (its own peak),
    an open fold's lower estimate and an unchecked fold's peak were drawn as refined
    peaks or not at all. Members of a copy of the file edited by hand: one per kind, and
    two at the band's lower end (a fold's branch refined to it, an unchecked fold's peak
    there), which are no resonance peaks."""
    import shutil

    from mcfric import plot
    from mcfric.peaks import FOLD_FOUND, FOLD_OPEN, FOLD_UNCHECKED

    path = tmp_path / "folds.h5"
    shutil.copyfile(results, path)
    with h5py.File(path, "r+") as h5:
        assert np.all(h5["fold"][()] == 0)
        fold, pm = h5["fold"][()], h5["peak_metric"][()]
        pf = h5["peak_frequency"][()]
        dm, df = h5["peak_metric_down"][()], h5["peak_frequency_down"][()]
        for i, code in enumerate((FOLD_FOUND, FOLD_OPEN, FOLD_UNCHECKED)):
            fold[i, 0] = code
            dm[i, 0], df[i, 0] = 1.3 * pm[i, 0], pf[i, 0] - 0.05
        f0 = h5["frequency"][0]
        fold[3, 0], dm[3, 0], df[3, 0] = FOLD_FOUND, 1.3 * pm[3, 0], f0
        status = h5["peak_status"][()]
        fold[4, 0], status[4, 0], pf[4, 0] = FOLD_UNCHECKED, 1, f0
        h5["fold"][...], h5["peak_metric_down"][...] = fold, dm
        h5["peak_frequency_down"][...], h5["peak_frequency"][...] = df, pf
        h5["peak_status"][...] = status
    figs = []
    real = plot._figure
    monkeypatch.setattr(plot, "_figure", lambda *a: figs.append(real(*a)) or figs[-1])
    drawn = plot.results_figure(path, tmp_path / "f.png", indicator=False)
    lines = {ln.get_label(): ln for ln in figs[0].axes[0].lines}

    def points(label):
        ln = lines[label]
        return set(zip(np.round(ln.get_xdata(), 9), np.round(ln.get_ydata(), 15)))

    fx = "member peaks on a branch reached from above (a fold)"
    low = "member peaks beside a fold not followed or not checked (may lie higher)"
    assert points(fx) == {(round(df[0, 0], 9), round(dm[0, 0], 15))}
    assert points(low) == {(round(df[1, 0], 9), round(dm[1, 0], 15)),
                           (round(pf[2, 0], 9), round(pm[2, 0], 15))}
    refined = points("refined member peaks (every member)")
    assert (round(pf[2, 0], 9), round(pm[2, 0], 15)) not in refined
    assert (round(pf[1, 0], 9), round(pm[1, 0], 15)) in refined
    ends = points("member maxima at an end of the band (not resonance peaks)")
    assert {(round(f0, 9), round(dm[3, 0], 15)), (round(f0, 9), round(pm[4, 0], 15))} <= ends
    assert drawn["n_fold_lower"] == 2
    monkeypatch.undo()
    rc, out, err = call(["plot", path, "-o", tmp_path / "g.png", "--no-indicator"], capsys)
    assert rc == 0 and "2 lower estimates beside a fold, drawn as triangles" in out, (out, err)


def test_a_point_between_two_failed_ones_is_a_marker():
    from mcfric import plot
    y = np.array([1.0, np.nan, 2.0, np.nan, 3.0, 4.0, np.nan, 5.0])
    assert list(np.flatnonzero(plot._alone(y))) == [0, 2, 7]


def test_the_hbm_figure_refuses_shapes_that_do_not_match(tmp_path):
    from mcfric import plot
    f = np.linspace(10, 20, 5)
    with pytest.raises(ValueError, match="expected freq_hz"):
        plot.hbm_figure(f, np.ones((4, 2)), np.ones(5), np.ones(5, bool), tmp_path / "h.png")
    assert not (tmp_path / "h.png").exists()


def test_verify_panels_say_what_they_cannot_show(tmp_path):
    """A panel whose integration did not settle, or whose harmonic balance failed (a
    NaN: no curve), says so in its title; the legend is on the first panel only."""
    import mcfric
    from mcfric import plot
    from mcfric.verify import verify
    vs = verify(mcfric.two_beam(), [35.28, 60.0], 0.03, 15000.0, 0.5, harmonics=3,
                max_periods=3)
    assert not any(v.periodic for v in vs)
    vs[1].multi[:] = np.nan
    titles = plot.verify_figure(vs, tmp_path / "v.png")["titles"]
    assert "35.28 Hz: time integration NOT periodic (not settled)" == titles[0]
    assert "H = 3 not converged" in titles[1]


def test_a_file_where_nothing_converged_says_so(results, tmp_path):
    """Every point failed (the flags set in a copy): the legend said '20 drawn' over an
    empty axis."""
    import shutil

    from mcfric import plot
    copy = tmp_path / "none.h5"
    shutil.copy(results, copy)
    with h5py.File(copy, "r+") as h5:
        h5["converged"][...] = False
    drawn = plot.results_figure(copy, tmp_path / "none.png", indicator=False)
    assert drawn["legend"][0] == "ensemble (20 members: no point in the window converged)"
    assert drawn["n_not_converged"] == 20 * 60


def test_the_legend_lies_inside_the_figure(tmp_path, monkeypatch):
    """The acceleration figure of a run with bounds: ten entries, two of them 93 and 100
    characters long. Unwrapped, the two columns ran past both edges of the figure."""
    from mcfric import config, ensemble, plot
    saved = []
    monkeypatch.setattr(plot, "_save", lambda fig, out, dpi: saved.append(fig))
    cfg = config.load({"model": {"preset": "two-beam"}, "frequency": {"n": 60},
                       "sampling": {"samples": 50}})
    path = ensemble.run(cfg, tmp_path / "r.h5", progress=False).path
    drawn = plot.results_figure(path, tmp_path / "r.png", quantity="acceleration")
    assert len(drawn["legend"]) == 10 and max(map(len, drawn["legend"])) >= 90
    fig = saved[-1]
    fig.canvas.draw()
    box, legend = fig.bbox, fig.legends[0].get_window_extent()
    assert box.x0 <= legend.x0 and legend.x1 <= box.x1


def test_a_lower_bound_of_0_is_marked_on_the_axis(tmp_path):
    """Two beams on 50 frequencies: the certificate proves nothing above 0 at one of
    them near 41 Hz. The log axis cannot show 0: the red line broke there and the band
    ran down to the axis's floor, which read as a bound. Marked on the axis, named."""
    from mcfric import config, ensemble, plot
    from mcfric.bounds import read_bounds

    cfg = config.load({"model": {"preset": "two-beam"}, "frequency": {"n": 50},
                       "sampling": {"samples": 5}})
    path = ensemble.run(cfg, tmp_path / "r.h5", progress=False).path
    zero = read_bounds(path).certificate.lower == 0
    assert zero.any()
    label = "lower bound 0 (nothing above 0 proved), on the axis"
    assert label in plot.results_figure(path, tmp_path / "r.png")["legend"]
    # outside the window of those frequencies nothing is marked
    f0 = float(read_bounds(path).freq_hz[zero].max())
    window = (f0 + 5, 150.0)
    assert label not in plot.results_figure(path, tmp_path / "w.png", f_window=window)["legend"]


def test_identical_member_peaks_are_counted_on_their_dot(tmp_path, monkeypatch):
    """Two beams, 100 members: the members whose dampers stick share one refined peak,
    drawn as one dot. Its label is the count of peaks within ``STACK_CELL`` of it in axes
    fractions (a pixel or two), counted here plainly from the file; a scattered cloud
    carries no label, and a zoom that spreads a cluster apart drops it."""
    from mcfric import config, ensemble, plot
    from mcfric.store import iter_records

    saved = []
    monkeypatch.setattr(plot, "_save", lambda fig, out, dpi: saved.append(fig))
    cfg = config.load({"model": {"preset": "two-beam"}, "frequency": {"n": 60},
                       "sampling": {"samples": 100}})
    path = ensemble.run(cfg, tmp_path / "r.h5", progress=False).path
    pm, pf = [], []
    for _, arr in iter_records(path, ["peak_metric", "peak_frequency"]):
        pm.append(arr["peak_metric"].ravel())
        pf.append(arr["peak_frequency"].ravel())
    pm, pf = np.concatenate(pm), np.concatenate(pf)

    def labels(**window):
        drawn = plot.results_figure(path, tmp_path / "r.png", **window)
        ax = saved[-1].axes[0]
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        out = []
        for t in ax.texts:
            x, y = t.xy
            near_dot = ((np.abs(pf - x) <= 0.0015 * (x1 - x0))
                        & (np.abs(np.log10(pm / y)) <= 0.003 * np.log10(y1 / y0)))
            assert int(t.get_text().replace(",", "")) == np.count_nonzero(near_dot)
            assert np.count_nonzero(near_dot) >= max(plot.STACK_MIN, 0.05 * len(pm))
            out.append((x, y))
        said = any("a number: peaks in one dot" in t for t in drawn["legend"])
        assert said == bool(out)
        return out

    whole = labels()
    assert len(whole) >= 1
    # the stuck members' peak: the dot counted at the first mode
    assert any(abs(x - 16.2) < 0.2 for x, _ in whole)
    labels(f_window=(15.0, 18.0))
    # a scattered cloud: no dot of twenty; thirty at one point: one
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 1, (500, 2))
    assert plot._stacks(xy) == []
    xy[:30] = 0.4
    assert plot._stacks(xy) == [(0, 30)]
    # thirty within a pixel: one dot; the same thirty zoomed tenfold (spread over ten
    # pixels, as on a window a tenth as wide): no label
    xy[:30, 0] = 0.4 + np.linspace(0, 0.001, 30)
    assert [k for _, k in plot._stacks(xy)] == [30]
    xy[:30, 0] = 0.4 + np.linspace(0, 0.01, 30)
    assert plot._stacks(xy) == []
