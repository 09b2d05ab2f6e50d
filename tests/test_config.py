"""Configuration: defaults = the paper, round trip of the printed TOML, merging, overrides,
and that errors name the key. (Every bad-config row of docs/configuration.md runs in
test_cli.py.)"""

import json
import re
import tomllib

import numpy as np
import pytest

from mcfric import config, presets
from mcfric.config import ConfigError


def same_model(a, b):
    fa, za, ua = a.modal_arrays()
    fb, zb, ub = b.modal_arrays()
    return (np.array_equal(fa, fb) and np.array_equal(za, zb) and np.array_equal(ua, ub)
            and np.array_equal(a.force, b.force) and a.topology == b.topology
            and a.n_dampers == b.n_dampers)


@pytest.mark.parametrize("name", presets.PRESETS)
def test_printed_template_is_complete_and_round_trips(name):
    text = config.template(name)
    raw = tomllib.loads(text)
    # every key of the schema is in the printed file, nothing else
    for sec, spec in config.SPEC.items():
        assert sec in raw
        for k in spec:
            if k != "beam" or sec != "model":
                assert k in raw[sec], f"{sec}.{k} missing from the template"
    cfg = config.validate(raw)              # complete on its own: no defaults needed
    assert cfg.data == config.load(name).data
    assert cfg.toml() == text


@pytest.mark.parametrize("name", presets.PRESETS)
def test_defaults_are_the_presets_and_the_paper(name):
    cfg = config.load(name)
    assert same_model(cfg.model(), presets.preset(name))
    s = cfg["sampling"]
    assert s["mu0"] == {"dist": "uniform", "low": 0.0, "high": 1.0}
    assert s["kc"] == {"dist": "uniform", "low": 0.0, "high": 15000.0}
    assert s["N0"] == {"dist": "fixed", "value": 0.5}
    assert s["samples"] == 2000 and s["mistuning"] == 0.0
    f = cfg.frequencies()
    assert len(f) == 1000 and f[0] == 10.0 and f[-1] == 150.0


def test_embedded_default_is_eight_beam_at_1_1_newton():
    cfg = config.load(None)
    assert cfg["model"]["preset"] == "eight-beam"
    assert cfg.model().excitation.F0 == 1.1
    assert cfg.model().excitation.pattern == "mode" and cfg.model().n_beams == 8


def test_a_preset_with_another_beam_count_is_renamed():
    """``disk-72`` with 120 blades is not ``disk-72``: unless a name is given, the count
    follows the preset's name; the preset's own count and a given name are kept; the
    name is a label, not part of the run's identity (``--resume``). ``Config.replace``
    renames the same way."""
    def name(model, **kw):
        return config.load({"model": model}, kw or None).model().name

    assert name({"preset": "disk-72", "n_beams": 120}) == "disk-72 (120 beams)"
    assert name({"preset": "disk-24", "n_beams": np.int64(72)}) == "disk-24 (72 beams)"
    assert name({"preset": "eight-beam", "n_beams": 12}) == "eight-beam (12 beams)"
    assert name({"preset": "disk-72", "n_beams": 72}) == "disk-72"
    assert name({"preset": "disk-24", "n_beams": 30, "name": "rig B"}) == "rig B"
    assert name({"preset": "disk-24", "n_beams": 30},
                **{"model.name": ("rig C", "--name")}) == "rig C"
    a = config.load({"model": {"preset": "disk-24", "n_beams": 30}})
    b = config.load({"model": {"preset": "disk-24", "n_beams": 30, "name": "disk-30"}})
    assert a.json() != b.json() and a.json(identity=True) == b.json(identity=True)
    assert config.first_difference(a.identity(), a.replace("model.n_beams", 31).identity()) \
        == "model.n_beams"
    # Config.replace renames as load does, but never a given name
    assert a.replace("model.n_beams", 31).model().name == "disk-24 (31 beams)"
    assert a.replace("model.n_beams", 24).model().name == "disk-24"
    assert config.load("disk-72").replace("model.n_beams", 96).model().name \
        == "disk-72 (96 beams)"
    assert b.replace("model.n_beams", 31).model().name == "disk-30"


def test_overrides_apply_and_name_their_flag():
    cfg = config.load("two-beam", {"excitation.F0": (0.72, "--F0"),
                                   "frequency.n": (50, "--n-freq"),
                                   "sampling.samples": (None, "--samples")})
    assert cfg.model().excitation.F0 == 0.72
    assert cfg.model().excitation.pattern == "single"     # the preset's pattern is kept
    assert len(cfg.frequencies()) == 50 and cfg.samples == 2000
    with pytest.raises(ConfigError) as e:
        config.load("two-beam", {"excitation.F0": (-1.0, "--F0")})
    assert e.value.key == "--F0"
    # a bare value failed in tuple unpacking (TypeError); a list had no .items()
    for bad in ({"sampling.samples": 5}, [1], {"sampling.samples": (5,)}):
        with pytest.raises(ConfigError, match=r"^overrides: expected \{dotted key: "):
            config.load("two-beam", bad)


def test_a_vanishing_force_is_refused():
    """F0 = 1e-150 N ran, and its members' squared responses underflowed: 388,807 of
    2,000,000 points fell outside the searched bounds ("please report"); F0 below
    1e-12 N is refused, 1e-12 N itself accepted."""
    with pytest.raises(ConfigError, match=r"--F0: expected a finite number >= 1e-12"):
        config.load("two-beam", {"excitation.F0": (1e-150, "--F0")})
    assert config.load("two-beam", {"excitation.F0": (1e-12, "--F0")}).model().excitation.F0 \
        == 1e-12


def test_a_slip_force_beyond_a_stuck_damper_is_refused():
    """mu0 N0 near 1e308 made the force limit 4/pi mu0 N0 inf and a response inf: the
    draws' reach is held to 1e12 N, the API's arrays too; a truncated normal open above
    (allowed for mu0 and N0) is taken at 8.3 std above its mean."""
    from mcfric import hbm, two_beam
    from mcfric.validators import InputError

    fixed = {"dist": "fixed", "value": 1e12}          # with mu0 up to 1: exactly at the limit
    config.load("two-beam").replace("sampling.N0", fixed)
    with pytest.raises(ConfigError, match=r"sampling.mu0 x sampling.N0: expected draws with "
                                          r"mu0 N0 of at most 1e\+12 N .* reach 1.1e\+12"):
        config.load("two-beam").replace("sampling.N0", {"dist": "fixed", "value": 1.1e12})
    open_top = {"dist": "truncnormal", "mean": 0.6, "std": 0.1, "low": 0.0,
                "high": float("inf")}
    cfg = config.load("two-beam", {"sampling.mu0": (open_top, "--mu0"),
                                   "bounds.F_lim": (5.0, "--F-lim")})
    assert cfg.samples > 0
    with pytest.raises(InputError, match="mu0 x N0: expected mu0 N0 of at most 1e\\+12 N"):
        hbm.solve(two_beam(0.22), [30.0], 1e300, 6000.0, 0.5)


def test_file_merges_key_by_key_and_replaces_distribution_tables(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[model]\npreset = "two-beam"\n[frequency]\nn = 40\n'
                 '[sampling.kc]\ndist = "normal"\nmean = 6000.0\nstd = 500.0\n'
                 '[bounds]\nk_max = 9000.0\n')    # a normal kc has no upper limit
    cfg = config.load(p)
    assert cfg["frequency"] == {"f_min": 10.0, "f_max": 150.0, "n": 40, "spacing": "linear"}
    assert cfg["sampling"]["kc"] == {"dist": "normal", "mean": 6000.0, "std": 500.0}
    assert cfg.model().n_beams == 2


def test_per_beam_override_fig_10b(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[model]\npreset = "two-beam"\n[[model.beam]]\nbeam = 2\n'
                 'freq_hz = [16.2, 108.0]\n')
    m = config.load(p).model()
    assert m.beams[0].freq_hz.tolist() == [16.2, 105.8]
    assert m.beams[1].freq_hz.tolist() == [16.2, 108.0]
    # the override survives the printed form
    again = config.validate(tomllib.loads(config.load(p).toml()))
    assert again.model().beams[1].freq_hz.tolist() == [16.2, 108.0]


def test_log_spacing_and_metric_beams():
    cfg = config.load({"frequency": {"spacing": "log", "n": 5, "f_min": 10.0,
                                     "f_max": 1000.0}, "metric": {"beams": [2, 3]}})
    np.testing.assert_allclose(cfg.frequencies(), [10, 10 ** 1.5, 100, 10 ** 2.5, 1000])
    assert cfg.metric_beams() == [1, 2]


def test_identity_ignores_run_and_bounds():
    a = config.load("two-beam")
    b = a.replace("run.threads", 1).replace("run.chunk", 7).replace("bounds.k_max", 1.0)
    assert a.json(identity=True) == b.json(identity=True)
    assert a.json() != b.json()
    c = a.replace("sampling.seed", 1)
    assert config.first_difference(a.identity(), c.identity()) == "sampling.seed"


def test_numpy_booleans_are_booleans_and_words_are_not():
    cfg = config.load("two-beam").replace("bounds.certify", np.False_)
    assert cfg.data["bounds"]["certify"] is False       # a Python bool, JSON-safe
    assert '"certify": false' in cfg.json()
    assert config.load("eight-beam").replace("bounds.certify_moments",
                                           np.True_).data["bounds"]["certify_moments"] is True
    with pytest.raises(ValueError, match="^bounds.certify: expected true or false"):
        config.load("two-beam").replace("bounds.certify", "no")


def test_config_json_round_trips_floats_exactly():
    cfg = config.load("eight-beam", {"excitation.F0": (0.1 + 0.2, "--F0")})
    back = json.loads(cfg.json())
    assert back["excitation"]["F0"] == 0.1 + 0.2


@pytest.mark.parametrize("raw, key", [
    ({"sampling": {"samples": 0}}, "sampling.samples"),
    ({"sampling": {"samples": 2.5}}, "sampling.samples"),
    ({"sampling": {"samples": True}}, "sampling.samples"),
    ({"frequency": {"f_min": float("nan")}}, "frequency.f_min"),
    ({"frequency": 3}, "frequency"),
    # a band narrower than rounding: the grid repeats frequencies (the run crashed, a
    # .partial left, before it was refused)
    ({"frequency": {"f_min": 10.0, "f_max": 10.000000000001}}, "frequency.n"),
    ({"frequency": {"f_min": 999999.9999999, "f_max": 1e6, "spacing": "log"}},
     "frequency.n"),
    ({"bogus": {}}, "bogus"),
    ({"model": {"table": {"shapes": [[1.0, 2.0], [3.0]]}}}, "model.table.shapes"),
    ({"model": {"table": {"positions": [1, 2]}}}, "model.table.positions"),
    ({"model": {"beam": [{"beam": 1, "zeta": [0.01]}]}}, "model.beam[1].zeta"),
    ({"model": {"beam": [{"beam": 1}, {"beam": 1}]}}, "model.beam[2].beam"),
    ({"model": {"beam": [{"freq_hz": [16.0, 100.0]}]}}, "model.beam[1].beam"),
    ({"model": {"beam": {"beam": 1}}}, "model.beam"),
    ({"sampling": {"mu0": 0.5}}, "sampling.mu0"),
    ({"sampling": {"mu0": {"low": 0.0, "high": 1.0}}}, "sampling.mu0.dist"),
    ({"sampling": {"kc": {"dist": "uniform", "low": "0", "high": 1.0}}}, "sampling.kc.low"),
    ({"metric": {"beams": "some"}}, "metric.beams"),
    ({"metric": {"beams": [1, 1]}}, "metric.beams"),
    ({"excitation": {"mode": -1}}, "excitation.mode"),
    ({"run": {"threads": 10 ** 6}}, "run.threads"),
    ({"run": {"scheduler": "http://10.0.0.5:8786"}}, "run.scheduler"),
    ({"bounds": {"certify_budget": "many"}}, "bounds.certify_budget"),
    ({"bounds": {"certify_budget": 0}}, "bounds.certify_budget"),
    ({"model": "eight-beam"}, "model"),
    ({"model": {"table": {"shapes": [[2.55, 0.99, 0.0], [-1.84, 2.18, 0.0]]}}},
     "model.table.shapes"),                 # zero at the drive: every response zero
    ({"model": {"table": {"shapes": [[2.55, 0.0, 0.48], [-1.84, 0.0, 1.42]]}}},
     "model.table.shapes"),                 # zero at the output
    ({"model": {"preset": "two-beam",       # the driven beam's own shapes are to blame
                "beam": [{"beam": 1, "shapes": [[2.55, 0.99, 0.0], [-1.84, 2.18, 0.0]]}]}},
     "model.beam[1].shapes"),
])
def test_errors_name_the_key(raw, key):
    with pytest.raises(ConfigError) as e:
        config.load(raw)
    assert e.value.key == key
    assert "\n" not in str(e.value)


def test_a_toml_date_is_named_as_written(tmp_path):
    path = tmp_path / "d.toml"
    path.write_text("[model]\nname = 1979-05-27\n")
    with pytest.raises(ConfigError) as e:
        config.load(path)
    assert e.value.key == "model.name"
    assert str(e.value).endswith("got the date or time 1979-05-27")


def test_a_toml_file_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf[sampling]\nsamples = 3\n")
    assert config.load(path)["sampling"]["samples"] == 3


def test_validate_without_defaults_reports_missing_keys():
    raw = config.defaults("two-beam")
    del raw["solver"]["tol"]
    with pytest.raises(ConfigError) as e:
        config.validate(raw)
    assert e.value.key == "solver.tol"


def test_every_toml_example_in_the_docs_is_valid():
    """Every plain ```toml block of the README and docs/ is a run configuration and must validate;
    TOML that is not one (e.g. a modal-table file) uses an info string: ```toml table-file."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    docs = [root / "README.md", *sorted((root / "docs").glob("*.md"))]
    blocks = [b.split("```", 1)[0] for p in docs for b in p.read_text().split("```toml\n")[1:]]
    assert blocks
    for b in blocks:
        config.load(tomllib.loads(b))


def test_modal_table_from_a_uff_file(tmp_path):
    """[model.table] file + nodes: the table read from UFF 55 replaces the numbers."""
    pytest.importorskip("pyuff")
    from mcfric.modal_io import write_modal_table_uff55
    from mcfric.model import TABLE_1

    write_modal_table_uff55(tmp_path / "beam.uff", TABLE_1, nodes={1: 101, 2: 102, 3: 103})
    p = tmp_path / "c.toml"
    p.write_text('[model]\npreset = "two-beam"\n[model.table]\nfile = "beam.uff"\n'
                 'nodes = {contact = 101, output = 102, drive = 103}\n'
                 '[[model.beam]]\nbeam = 2\nfile = "beam.uff"\n'
                 'nodes = {contact = 101, output = 102, drive = 103}\n')
    cfg = config.load(p)
    m = cfg.model()
    for t in m.beams:
        np.testing.assert_allclose(t.freq_hz, TABLE_1.freq_hz, rtol=1e-5)
        np.testing.assert_allclose(t.shapes, TABLE_1.shapes, rtol=1e-5)
    assert "file" not in cfg["model"]["table"]          # the numbers are recorded instead
    assert config.validate(tomllib.loads(cfg.toml())).data == cfg.data


@pytest.mark.parametrize("table, key", [
    ('file = "missing.uff"\nnodes = {contact = 1, output = 2, drive = 3}', "model.table.file"),
    ('file = "beam.uff"\nnodes = {contact = 101, output = 102}', "model.table.nodes"),
    ('file = "beam.uff"\nnodes = {contact = 101, output = 102, drive = 103}\nzeta = [0.1]',
     "model.table.zeta"),
    ('file = "beam.uff"\nnodes = {contact = 101, output = 102, drive = 103}\nfoo = 1',
     "model.table.foo: unknown key (with file: file, nodes"),
])
def test_bad_modal_table_file(tmp_path, table, key):
    pytest.importorskip("pyuff")
    from mcfric.modal_io import write_modal_table_uff55
    from mcfric.model import TABLE_1

    write_modal_table_uff55(tmp_path / "beam.uff", TABLE_1, nodes={1: 101, 2: 102, 3: 103})
    p = tmp_path / "c.toml"
    p.write_text(f"[model.table]\n{table}\n")
    with pytest.raises(config.ConfigError) as e:
        config.load(p)
    assert str(e.value).startswith(key) and "\n" not in str(e.value)


def test_a_source_that_is_no_configuration_file_is_one_line(tmp_path, monkeypatch):
    """An empty name, a directory, a results (HDF5) file, a missing file: one line that
    says what it is, not a decoding error."""
    import h5py

    h5 = tmp_path / "r.h5"
    h5py.File(h5, "w").close()
    for source, words in (("", "expected a preset"), (tmp_path, "a directory"),
                          (h5, "an HDF5 file (results?)"),
                          (tmp_path / "nope.toml", "no such file"),
                          ("/dev/null", "no key read from a device or a pipe")):
        with pytest.raises(config.ConfigError, match=re.escape(words)) as e:
            config.load(source)
        assert len(str(e.value).splitlines()) == 1
    # a results file larger than any configuration is still called one (it was "more
    # than 16 MiB"), and the message says how to get its configuration
    from mcfric.config import loading
    monkeypatch.setattr(loading, "MAX_TOML_BYTES", 100)
    assert h5.stat().st_size > 100
    with pytest.raises(config.ConfigError, match=re.escape(
            f"an HDF5 file (results?), not a TOML configuration (`mcfric config {h5} > "
            f"run.toml` writes a results file's)")):
        config.load(h5)


def test_a_pipe_is_read_as_a_file_unless_it_gives_no_key(tmp_path):
    """`mcfric run <(...)` reads the pipe; one that gives no key (only a comment) is
    refused, as /dev/null is; an empty regular file is a configuration of defaults."""
    import os
    import threading

    def piped(text):
        r, w = os.pipe()
        threading.Thread(target=lambda: (os.write(w, text.encode()), os.close(w))).start()
        return f"/dev/fd/{r}", r

    for text, ok in (('model.preset = "two-beam"\n', True), ("# nothing\n\n", False)):
        path, r = piped(text)
        try:
            if ok:
                assert config.load(path).model().n_beams == 2
            else:
                with pytest.raises(ConfigError, match="no key read from a device or a pipe"):
                    config.load(path)
        finally:
            os.close(r)
    (tmp_path / "empty.toml").write_text("")
    assert config.load(tmp_path / "empty.toml").model().name == config.load().model().name


def test_replace_takes_numpy_values_as_a_toml_file_gives_them():
    """numpy scalars inside a list, or an array, for a list key: 'cannot render
    np.int64(1)' and numpy's 'truth value is ambiguous' before."""
    cfg = config.load("eight-beam")
    for beams in ([np.int64(1), np.int64(3)], np.array([1, 3])):
        c = cfg.replace("metric.beams", beams)
        assert c["metric"]["beams"] == [1, 3] and "beams = [1, 3]" in c.toml()
    assert cfg.replace("excitation.F0", np.float64(0.5))["excitation"]["F0"] == 0.5


@pytest.mark.parametrize("source", [3, ["eight-beam"], 1.5])
def test_a_source_of_another_type_is_named(source):
    # Path() raised a TypeError that named no argument
    with pytest.raises(ValueError, match=f"^source: expected a preset name, a TOML file's "
                                         f"path, a dict or None, got {type(source).__name__}$"):
        config.load(source)


@pytest.mark.parametrize("toml, override, key", [
    ('sampling.samples = "x"', {"sampling.samples": (3, "--samples")}, "sampling.samples"),
    ("frequency.n = -5", {"frequency.n": (5, "--n-freq")}, "frequency.n"),
    ('bounds.certify = "yes"', {"bounds.certify": (False, "--no-certify")}, "bounds.certify"),
])
def test_a_bad_value_in_the_file_is_named_though_a_flag_replaces_it(tmp_path, toml, override,
                                                                    key):
    """A file's bad value hidden by a flag ran silently (the file fails without it)."""
    path = tmp_path / "c.toml"
    path.write_text(toml + "\n")
    with pytest.raises(config.ConfigError, match=rf"^{key}: .*in the configuration file, "
                                                  rf"though {override[key][1]} replaces it"):
        config.load(str(path), override)


def test_a_file_made_consistent_by_a_flag_still_loads(tmp_path):
    """Only each replaced value is checked on its own: f_min = 200 above the preset's
    150 Hz is fine with --f-max 300."""
    path = tmp_path / "c.toml"
    path.write_text("frequency.f_min = 200.0\n")
    cfg = config.load(str(path), {"frequency.f_max": (300.0, "--f-max")})
    assert cfg.data["frequency"]["f_max"] == 300.0
