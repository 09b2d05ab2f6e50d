"""Modal tables from files: UFF 55 round trip within UFF's printed precision, conventions
(mass normalisation, units, damping, directions, complex modes), CSV/TOML tables, and
one-line errors for bad files."""

import math
import sys

import numpy as np
import pytest

from mcfric.core.receptance import receptance
from mcfric.measured import read_measured
from mcfric.modal_io import UFF_RTOL, read_modal_table, write_modal_table_uff55
from mcfric.model import TABLE_1, ModalTable, Model

pyuff = pytest.importorskip("pyuff")

NODES = {1: 101, 2: 102, 3: 103}


def rounded(x):
    """What UFF's E13.5 fields print: 6 significant digits."""
    return np.array([float(f"{v:.5e}") for v in np.ravel(x)]).reshape(np.shape(x))


def awkward_table():
    """Three modes whose values all lose digits in E13.5."""
    rng = np.random.default_rng(7)
    return ModalTable(freq_hz=[16.2034567, 105.8123456, 288.765432],
                      zeta=[0.00171234567, 0.0071234567, 0.0123456789],
                      shapes=rng.normal(0, 2, (3, 3)) + 0.123456789, positions=(1, 2, 3))


def receptance_matrix(table, omega):
    """d_pq for all position pairs, shape (n_pos, n_pos, n_f), m/N."""
    u = table.shapes
    n = u.shape[1]
    return np.array([[receptance(omega, table.freq_hz, table.zeta, u[:, p], u[:, q])
                      for q in range(n)] for p in range(n)])


def printed_precision_bound(table, omega, rel=UFF_RTOL):
    """First-order bound on |d_pq(read) - d_pq(original)| when every f_k, zeta_k and
    u_k,p is perturbed by at most ``rel`` relative (independent of the reader)."""
    wk = 2 * np.pi * table.freq_hz[:, None]
    z = table.zeta[:, None]
    w = omega[None, :]
    D = wk * wk + 2j * z * wk * w - w * w
    dD_dw = np.abs(2 * wk + 2j * z * w) * rel * wk      # |dD/dw_k| * delta w_k
    dD_dz = np.abs(2j * wk * w) * rel * z                # |dD/dzeta_k| * delta zeta_k
    u = table.shapes
    n = u.shape[1]
    out = np.zeros((n, n, omega.size))
    for p in range(n):
        for q in range(n):
            T = np.abs(u[:, p] * u[:, q])[:, None] / np.abs(D)
            out[p, q] = np.sum(T * (2 * rel + (dD_dw + dD_dz) / np.abs(D)), axis=0)
    return out


def one_line(excinfo, *words):
    msg = str(excinfo.value)
    assert "\n" not in msg, msg
    for w in words:
        assert w.lower() in msg.lower(), msg
    return msg


def write55(path, modes, *, units=None, analysis_type=2, data_ch=2, ndv=3):
    """A UFF 55 file written by pyuff itself (independent of mcfric's writer).

    ``modes``: list of dicts with mode_n, freq, modal_m, zeta, eta, nodes, r (list of
    ndv arrays, real or complex).
    """
    dsets = []
    if units is not None:
        dsets.append({"type": 164, "units_code": 9, "units_description": "user",
                      "temp_mode": 1, "length": units[0], "force": units[1], "temp": 1.0,
                      "temp_offset": 273.15})
    for m in modes:
        d = {"type": 55, "id1": "test", "model_type": 1, "analysis_type": analysis_type,
             "data_ch": data_ch, "spec_data_type": 8, "load_case": 1,
             "mode_n": m["mode_n"], "node_nums": np.array(m["nodes"]),
             "r1": m["r"][0], "r2": m["r"][1], "r3": m["r"][2]}
        if ndv == 6:
            d.update(r4=m["r"][3], r5=m["r"][4], r6=m["r"][5])
        if analysis_type == 2:
            d.update(freq=m["freq"], modal_m=m.get("modal_m", 0.0),
                     modal_damp_vis=m.get("zeta", 0.0), modal_damp_his=m.get("eta", 0.0))
        else:
            d.update(eig=m["eig"], modal_a=1j, modal_b=1.0 + 0j)
        dsets.append(d)
    pyuff.UFF(str(path)).write_sets(dsets, mode="overwrite")
    return path


def z_modes(table, nodes=(101, 102, 103), scale=1.0, **extra):
    """Modes of ``table`` as write55 input, shapes (times ``scale``) in Z."""
    out = []
    for k in range(table.n_modes):
        zero = np.zeros(len(nodes))
        out.append(dict(mode_n=k + 1, freq=float(table.freq_hz[k]),
                        zeta=float(table.zeta[k]), nodes=list(nodes),
                        r=[zero, zero, np.asarray(table.shapes[k], float) * scale], **extra))
    return out


# ---------------------------------------------------------------- round trip

def test_uff55_round_trip_reproduces_receptances(tmp_path):
    table = awkward_table()
    path = write_modal_table_uff55(tmp_path / "beam.uff", table, nodes=NODES)
    back = read_modal_table(path, positions=NODES)
    assert back.positions == (1, 2, 3)
    # exactly the printed values (6 significant digits), nothing else lost or added
    np.testing.assert_allclose(back.freq_hz, rounded(table.freq_hz), rtol=1e-15)
    np.testing.assert_allclose(back.zeta, rounded(table.zeta), rtol=1e-15)
    np.testing.assert_allclose(back.shapes, rounded(table.shapes), rtol=1e-15)
    # receptances over the band, including every resonance exactly
    omega = np.sort(np.concatenate([2 * np.pi * np.linspace(1, 400, 801),
                                    2 * np.pi * table.freq_hz]))
    d0 = receptance_matrix(table, omega)
    d1 = receptance_matrix(back, omega)
    bound = printed_precision_bound(table, omega)
    assert np.all(np.abs(d1 - d0) <= bound), np.max(np.abs(d1 - d0) / bound)
    # the bound is tight enough to mean something: well below 1 % at the peaks
    assert np.max(bound / np.abs(d0)) < 5e-3
    # and the same through the rounded table, to machine precision
    np.testing.assert_allclose(d1, receptance_matrix(
        ModalTable(rounded(table.freq_hz), rounded(table.zeta), rounded(table.shapes)),
        omega), rtol=1e-12)


def test_round_trip_paper_table_is_exact_and_builds_a_model(tmp_path):
    path = write_modal_table_uff55(tmp_path / "t1.uff", TABLE_1, nodes=NODES)
    back = read_modal_table(path, positions=NODES)
    for a in ("freq_hz", "zeta", "shapes"):
        np.testing.assert_array_equal(getattr(back, a), getattr(TABLE_1, a))
    # labels = node numbers when no mapping is given
    natural = read_modal_table(path)
    assert natural.positions == (101, 102, 103)
    model = Model.identical(natural, 2, contact=101, output=102, drive=103)
    np.testing.assert_array_equal(model.modal_arrays()[2],
                                  Model.identical(TABLE_1, 2).modal_arrays()[2])
    # a subset of nodes and modes, in the order asked
    sub = read_modal_table(path, positions=[103, 101], modes=[2])
    np.testing.assert_array_equal(sub.shapes, [[1.42, -1.84]])


def test_writer_refuses_to_overwrite(tmp_path):
    path = write_modal_table_uff55(tmp_path / "t.uff", TABLE_1)
    with pytest.raises(ValueError) as e:
        write_modal_table_uff55(path, TABLE_1)
    one_line(e, str(path), "exists")
    write_modal_table_uff55(path, TABLE_1.with_frequency(2, 108.0), overwrite=True)
    assert read_modal_table(path).freq_hz[1] == 108.0


# ---------------------------------------------------------------- conventions

def test_modal_mass_scales_shapes(tmp_path):
    # shapes 2u with modal mass 4 are u at unit modal mass
    path = write55(tmp_path / "m.uff", z_modes(TABLE_1, scale=2.0, modal_m=4.0))
    back = read_modal_table(path, positions=NODES)
    np.testing.assert_allclose(back.shapes, TABLE_1.shapes, rtol=1e-12)
    # modal mass 0 (unknown) and 1: taken as they are
    for m in (0.0, 1.0):
        path = write55(tmp_path / f"m{m}.uff", z_modes(TABLE_1, modal_m=m))
        np.testing.assert_allclose(read_modal_table(path, positions=NODES).shapes,
                                   TABLE_1.shapes, rtol=1e-12)


def test_units_dataset_164_is_honoured(tmp_path):
    # mm, N: receptance in mm/N is 1000x, so shapes are sqrt(1000)x the SI ones
    path = write55(tmp_path / "mm.uff", z_modes(TABLE_1, scale=math.sqrt(1000.0)),
                   units=(1000.0, 1.0))
    back = read_modal_table(path, positions=NODES)
    np.testing.assert_allclose(back.shapes, TABLE_1.shapes, rtol=1e-5)


def test_hysteretic_damping_only_gives_half_the_loss_factor(tmp_path):
    modes = z_modes(TABLE_1)
    for m in modes:
        m["eta"], m["zeta"] = 2 * m["zeta"], 0.0
    back = read_modal_table(write55(tmp_path / "h.uff", modes), positions=NODES)
    np.testing.assert_allclose(back.zeta, TABLE_1.zeta, rtol=1e-12)


def test_direction_is_chosen_or_must_be_given(tmp_path):
    modes = z_modes(TABLE_1)
    modes[1]["r"][0] = np.array([0.0, 0.1, 0.0])           # an X component in mode 2
    path = write55(tmp_path / "xz.uff", modes)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "X, Z", "direction=")
    np.testing.assert_array_equal(read_modal_table(path, direction=3).shapes,
                                  TABLE_1.shapes)
    np.testing.assert_array_equal(read_modal_table(path, direction=1, modes=[2]).shapes,
                                  [[0.0, 0.1, 0.0]])
    with pytest.raises(ValueError) as e:
        read_modal_table(path, direction=4)
    one_line(e, "direction", "1..3")


def test_six_dof_vectors(tmp_path):
    modes = z_modes(TABLE_1)
    for m in modes:
        m["r"] = m["r"] + [np.zeros(3), np.full(3, 0.0), np.zeros(3)]
    path = write55(tmp_path / "six.uff", modes, data_ch=3, ndv=6)
    np.testing.assert_array_equal(read_modal_table(path, positions=NODES).shapes,
                                  TABLE_1.shapes)


def test_scalar_modes_with_many_nodes(tmp_path):
    # NDV = 1 (data characteristic scalar), written by hand: pyuff cannot write it and
    # splits its values with a stride of 6 when reading, which the reader undoes
    rng = np.random.default_rng(3)
    nodes = list(range(11, 20))
    shapes = rng.normal(size=(2, len(nodes)))
    lines = []
    for k in range(2):
        lines += ["    -1", "    55", "scalar modes", "NONE", "NONE", "NONE", "NONE",
                  f"{1:10d}{2:10d}{1:10d}{8:10d}{2:10d}{1:10d}",
                  f"{2:10d}{4:10d}{1:10d}{k + 1:10d}",
                  f"{[20.0, 90.0][k]:13.5e}{1.0:13.5e}{0.01:13.5e}{0.0:13.5e}"]
        for n, v in zip(nodes, shapes[k]):
            lines += [f"{n:10d}", f"{v:13.5e}"]
        lines += ["    -1"]
    path = tmp_path / "scalar.unv"
    path.write_text("\n".join(lines) + "\n")
    back = read_modal_table(path)
    assert back.positions == tuple(nodes)
    np.testing.assert_allclose(back.shapes, rounded(shapes), rtol=1e-15)
    np.testing.assert_array_equal(back.freq_hz, [20.0, 90.0])


def test_nearly_real_complex_modes_are_rotated_and_accepted(tmp_path):
    rng = np.random.default_rng(5)
    modes = z_modes(TABLE_1)
    for k, m in enumerate(modes):
        noise = 0.005 * np.max(np.abs(m["r"][2])) * rng.normal(size=3)
        phase = np.exp(1j * (0.7 + 2.1 * k))
        m["r"] = [np.zeros(3, complex), np.zeros(3, complex),
                  (m["r"][2] + 1j * noise) * phase]
    path = write55(tmp_path / "c.uff", modes)
    back = read_modal_table(path, positions=NODES)
    # a mode's sign is arbitrary; receptances use products u_p u_q. The noise is 0.5 %
    # across the phase: the rotated real part errs at second order (measured 3e-5 of the
    # largest product), far below the 1e-3 a first-order error would give
    for k in range(2):
        exact = np.outer(TABLE_1.shapes[k], TABLE_1.shapes[k])
        np.testing.assert_allclose(np.outer(back.shapes[k], back.shapes[k]), exact,
                                   rtol=0, atol=2e-4 * np.abs(exact).max())
    with pytest.raises(ValueError) as e:
        read_modal_table(path, positions=NODES, max_imag=1e-4)
    one_line(e, str(path), "mode 1 is complex", "max_imag")


def test_complex_modes_are_rejected(tmp_path):
    modes = z_modes(TABLE_1)
    for m in modes:  # pyuff takes real/complex from r1 alone: all components complex
        m["r"] = [np.asarray(r, complex) for r in m["r"]]
    modes[1]["r"][2] = np.array([1.0, 1j, -1.0])             # travelling, not a real mode
    path = write55(tmp_path / "cx.uff", modes)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "mode 2 is complex", "real normal modes")
    eig = [dict(mode_n=1, eig=-0.2 + 100j, nodes=[1, 2], r=[np.zeros(2, complex)] * 3)]
    path = write55(tmp_path / "eig.uff", eig, analysis_type=3)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "complex-eigenvalue", "analysis type 3")


# ---------------------------------------------------------------- missing things

def test_missing_modes_nodes_and_zero_modes(tmp_path):
    path = write_modal_table_uff55(tmp_path / "t.uff", TABLE_1, nodes=NODES)
    with pytest.raises(ValueError) as e:
        read_modal_table(path, modes=[1, 3])
    one_line(e, str(path), "mode 3 not in the file", "modes: 1, 2")
    with pytest.raises(ValueError) as e:
        read_modal_table(path, positions={1: 101, 2: 999})
    one_line(e, str(path), "node 999 not in the file")

    modes = z_modes(TABLE_1)
    modes[1]["nodes"] = [101, 102, 104]
    path = write55(tmp_path / "gap.uff", modes)
    with pytest.raises(ValueError) as e:
        read_modal_table(path, positions=NODES)
    one_line(e, str(path), "node 103 missing from mode 2")

    modes = z_modes(TABLE_1)
    modes[0]["r"][2] = np.zeros(3)
    path = write55(tmp_path / "zero.uff", modes)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "mode 1 is zero", "modes=")
    np.testing.assert_array_equal(read_modal_table(path, modes=[2]).shapes, [[-1.84, 2.18,
                                                                               1.42]])
    modes = z_modes(TABLE_1)
    modes[1]["mode_n"] = 1
    path = write55(tmp_path / "dup.uff", modes)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "mode 1 appears twice")


# ---------------------------------------------------------------- bad files

def test_truncated_uff(tmp_path):
    path = write_modal_table_uff55(tmp_path / "t.uff", TABLE_1)
    text = path.read_text()
    for cut in (len(text) - 8, int(len(text) * 0.6), int(len(text) * 0.35)):
        bad = tmp_path / f"cut{cut}.uff"
        bad.write_text(text[:cut])
        with pytest.raises(ValueError) as e:
            read_modal_table(bad)
        one_line(e, str(bad), "truncated")


def test_wrong_dataset_type(tmp_path):
    path = tmp_path / "frf.uff"
    pyuff.UFF(str(path)).write_sets([{
        "type": 58, "func_type": 4, "rsp_node": 1, "rsp_dir": 3, "ref_node": 1,
        "ref_dir": 3, "orddenom_spec_data_type": 13, "x": np.array([1.0, 2.0]),
        "data": np.array([1.0 + 1j, 2.0])}], mode="overwrite")
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "no dataset 55", "found dataset types: 58")
    modes = z_modes(TABLE_1)
    path = write55(tmp_path / "static.uff", modes, analysis_type=2)
    text = path.read_text().replace("         1         2         2         8",
                                    "         1         5         2         8")
    path.write_text(text)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "analysis type 5", "frequency response")


def test_not_a_uff_file_and_missing_file(tmp_path):
    path = tmp_path / "junk.uff"
    path.write_text("freq_hz,zeta\n1,2\n")
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), "not a UFF file")
    with pytest.raises(ValueError) as e:
        read_modal_table(tmp_path / "none.uff")
    one_line(e, "none.uff", "not found")
    # a directory named like a file: said so, not "file not found" (CSV and UFF readers)
    for name in ("dir.uff", "dir.csv"):
        (tmp_path / name).mkdir()
        with pytest.raises(ValueError) as e:
            read_modal_table(tmp_path / name)
        one_line(e, name, "a directory, not a file")
        with pytest.raises(ValueError) as e:
            read_measured(tmp_path / name)
        one_line(e, name, "a directory, not a file")
    with pytest.raises(ValueError) as e:
        read_modal_table(tmp_path / "table.xlsx")
    one_line(e, "unknown file type", "format=")


def test_missing_pyuff_gives_install_hint(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)
    with pytest.raises(ImportError) as e:
        read_modal_table(tmp_path / "x.uff")
    one_line(e, 'pip install ".[uff]" in the clone')
    with pytest.raises(ImportError):
        write_modal_table_uff55(tmp_path / "x.uff", TABLE_1)


# ---------------------------------------------------------------- CSV and TOML

CSV = """# beam 6, paper Table 1
mode,freq_hz,zeta,u1,u2,u3
1,16.20,0.0017,2.55,0.99,0.48
2,105.8,0.0071,-1.84,2.18,1.42
"""

TOML = """
[table]
freq_hz = [16.20, 105.8]
zeta = [0.0017, 0.0071]
shapes = [[2.55, 0.99, 0.48], [-1.84, 2.18, 1.42]]
positions = [1, 2, 3]
"""


def test_csv_and_toml_tables(tmp_path):
    for name, text in (("t.csv", CSV), ("t.toml", TOML),
                       ("m.toml", TOML.replace("[table]", "[model.table]")),
                       ("bom.toml", "\ufeff" + TOML)):
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        back = read_modal_table(path)
        assert back.positions == TABLE_1.positions
        for a in ("freq_hz", "zeta", "shapes"):
            np.testing.assert_array_equal(getattr(back, a), getattr(TABLE_1, a))
    # relabel, select, and modal mass in a column
    path = tmp_path / "n.csv"
    path.write_text("freq_hz,zeta,modal_mass,u101,u102,u103\n"
                    "16.2,0.0017,4,5.1,1.98,0.96\n")
    back = read_modal_table(path, positions={1: 101, 3: 103})
    assert back.positions == (1, 3)
    np.testing.assert_allclose(back.shapes, [[2.55, 0.48]])


@pytest.mark.parametrize("text, words", [
    ("mode,freq_hz,u1,u2\n1,16.2,2.55,0.99\n", ["missing column", "zeta"]),
    ("mode,freq_hz,zeta\n1,16.2,0.0017\n", ["missing column", "u<position>"]),
    ("freq_hz,zeta,u1,shape2\n16.2,0.0017,2.55,0.99\n", ["unknown column", "shape2"]),
    ("freq_hz,zeta,u1\n16.2,0.0017\n", ["line 2", "2 fields"]),
    ("freq_hz,zeta,u1\n16.2,abc,1\n", ["line 2", "zeta", "not a number"]),
    ("freq_hz,zeta,u1\n-16.2,0.001,1\n", ["frequency must be > 0"]),
    ("mode,freq_hz,zeta,u1\n1,16.2,0.001,1\n7,105.8,2,1\n", ["mode 7", "<= 1", "got 2"]),
    ("freq_hz,zeta,u1\n", ["no modes"]),
])
def test_bad_csv_tables(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as e:
        read_modal_table(path)
    one_line(e, str(path), *words)


@pytest.mark.parametrize("kw, words", [
    # a set has no order ({3, 1} took the columns in the set's order); a string was read
    # label by label ("1" as [1]); modes=1 was a TypeError from iterating an int
    (dict(positions={3, 1}), "positions: expected None, a list of column numbers"),
    (dict(positions="1"), "positions: expected None, a list of column numbers"),
    (dict(modes=1), "modes: expected a sequence of mode numbers"),
    (dict(modes={1}), "modes: expected a sequence of mode numbers"),
])
def test_selections_without_an_order_are_refused(tmp_path, kw, words):
    path = tmp_path / "t.csv"
    path.write_text("mode,freq_hz,zeta,u1,u2,u3\n1,16.2,0.0017,2.55,0.99,0.48\n")
    with pytest.raises(ValueError) as e:
        read_modal_table(path, **kw)
    one_line(e, str(path), words)
    with pytest.raises(ValueError) as e:         # Path(None): a TypeError from os
        read_modal_table(None)
    one_line(e, "path: expected a file's path, got None")


def test_bad_toml_tables(tmp_path):
    path = tmp_path / "bad.toml"
    for text, words in ((TOML.replace("zeta = [0.0017, 0.0071]\n", ""), ["missing", "zeta"]),
                        (TOML + "foo = 1\n", ["unknown key", "foo"]),
                        ("x = [", ["not valid TOML"]),
                        ("[other]\na = 1\n", ["no modal table"])):
        path.write_text(text)
        with pytest.raises(ValueError) as e:
            read_modal_table(path)
        one_line(e, str(path), *words)
