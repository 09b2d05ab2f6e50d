"""The command line: every bad-configuration row of the table in docs/configuration.md,
the commands' outputs, and the wiring of `mcfric` with no arguments."""

import csv
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import h5py
import numba
import numpy as np
import pytest

from mcfric import cli, config, ensemble, hbm, plot, stop_signals

ROOT = Path(__file__).resolve().parents[1]
MARK = "<!-- bad-config-table -->"


def bad_config_rows():
    """Rows (input, message) of the bad-configuration table of the configuration docs."""
    for doc in (ROOT / "docs" / "configuration.md",):
        if doc.exists() and MARK in doc.read_text():
            text = doc.read_text()
            break
    else:
        raise AssertionError("no bad-configuration table in docs/configuration.md")
    table = text.split(MARK, 1)[1].split("<!-- /bad-config-table -->", 1)[0]
    rows = []
    for line in table.splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        if len(cells) != 3 or cells[0] in ("case", "---"):
            continue
        rows.append((cells[0], _code(cells[1]), _code(cells[2])))
    assert len(rows) >= 30
    return rows


def _code(cell):
    m = re.fullmatch(r"(`+)\s?(.*?)\s?\1", cell)
    assert m, f"not a code cell: {cell}"
    return m.group(2)


def call(argv, capsys):
    rc = cli.main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize("case, given, message", bad_config_rows(),
                         ids=[r[0] for r in bad_config_rows()])
def test_readme_bad_config_row(case, given, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if given.startswith("toml: "):
        (tmp_path / "bad.toml").write_text(given[len("toml: "):] + "\n")
        argv = ["run", "bad.toml", "-o", "out.h5"]
    else:
        argv = shlex.split(given)
        assert argv[0] == "mcfric"
        argv = argv[1:]
    before = sorted(os.listdir(tmp_path))
    rc, out, err = call(argv, capsys)
    assert rc == 2
    assert err == message + "\n"                       # exactly one line
    assert sorted(os.listdir(tmp_path)) == before      # nothing written


def test_too_many_threads(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    n = numba.config.NUMBA_NUM_THREADS
    rc, _, err = call(["run", "--threads", str(n + 1)], capsys)
    assert rc == 2
    assert err == (f"mcfric: error: --threads: expected an integer in 0..{n} (0 = all {n}), "
                   f"got {n + 1}\n")
    assert os.listdir(tmp_path) == []


def test_real_process_exit_code_and_no_traceback(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    (tmp_path / "bad.toml").write_text("sampling.mu0 = {dist = 'gamma'}\n")
    for args in (["run", "--samples", "0"], ["run", "bad.toml"], ["info", "nope.h5"],
                 ["run", "--bogus"]):
        r = subprocess.run([sys.executable, "-m", "mcfric", *args], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
        assert r.stderr.startswith("mcfric: error: ")
    assert sorted(os.listdir(tmp_path)) == ["bad.toml"]


@pytest.mark.parametrize("name", ["two-beam", "eight-beam"])
def test_config_prints_complete_toml(name, capsys):
    rc, out, _ = call(["config", name], capsys)
    assert rc == 0
    assert config.validate(tomllib.loads(out)).data == config.load(name).data
    assert "# " in out                                  # commented


def test_config_of_a_file_prints_its_complete_form(tmp_path, capsys):
    p = tmp_path / "c.toml"
    p.write_text('[model]\npreset = "two-beam"\n[sampling]\nsamples = 77\n')
    rc, out, _ = call(["config", str(p)], capsys)
    assert rc == 0
    cfg = config.validate(tomllib.loads(out))
    assert cfg.samples == 77 and cfg.model().n_beams == 2


def test_run_info_and_figure(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(["run", "two-beam", "--samples", "40", "--n-freq", "25", "--seed", "3",
                         "--F0", "0.72", "-o", "r.h5", "--no-progress"], capsys)
    assert rc == 0, err
    for text in ("samples: 40 of 40, 25 frequencies each: 1,000 points",
                 "not converged: 0 points", "wall time:", "results: r.h5",
                 "figure: r.png",
                 # the certificate's summary, without the progress output too
                 "upper within 1 % of its witness at"):
        assert text in out
    # the points per second are the ensemble's, the bounds' time apart (as stored)
    m = re.search(r"wall time: ([\d.]+) s for 40 samples: bounds ([\d.]+) s, ensemble "
                  r"([\d.]+) s \(kernel [\d.]+ s\), ([\d,]+) points/s in the ensemble", out)
    wall, b, ens, rate = (float(g.replace(",", "")) for g in m.groups())
    assert abs(wall - b - ens) <= 0.011 and b > 0
    # the printed time is rounded to 0.01 s (a warm ensemble takes ~0.07 s: 7 % of it)
    assert 1000 / (ens + 0.005) - 1 <= rate <= 1000 / max(ens - 0.005, 1e-9) + 1
    assert (tmp_path / "r.png").stat().st_size > 10000
    with h5py.File(tmp_path / "r.h5") as h5:
        cfg = config.validate(tomllib.loads(h5.attrs["config"]))
        assert cfg.model().excitation.F0 == 0.72 and cfg.seed == 3
        assert h5.attrs["numba_version"] == numba.__version__
        assert h5.attrs["bounds_time_s"] == pytest.approx(b, abs=0.006)
        assert h5.attrs["wall_time_s"] == pytest.approx(wall, abs=0.006)
    rc, out, _ = call(["info", "r.h5"], capsys)
    assert rc == 0
    assert "(complete)" in out and "two-beam: 2 beams, 1 damper, linear" in out
    assert "converged:   1,000 of 1,000 points (0 not converged)" in out
    assert re.search(r"response\s+\(sample, frequency, beam\)\s+40 x 25 x 2", out)
    # the bounds as run printed them (searched, then certified) and the group's datasets
    assert "bounds:      searched bounds at 25 frequencies" in out
    assert re.search(r"\n {13}certified \(first order", out)
    assert re.search(r"bounds/ \(group\)\s+\d+ datasets per frequency: .*upper_certified", out)
    # the same run again: nothing to do; another seed: refused, exit 2, file untouched
    rc, out, _ = call(["run", "two-beam", "--samples", "40", "--n-freq", "25", "--seed", "3",
                       "--F0", "0.72", "-o", "r.h5", "--no-progress"], capsys)
    assert rc == 0 and "already holds this run" in out
    mtime = (tmp_path / "r.h5").stat().st_mtime_ns
    rc, _, err = call(["run", "two-beam", "--samples", "40", "--n-freq", "25", "-o", "r.h5"],
                      capsys)
    assert rc == 2 and err.count("\n") == 1 and "--force" in err
    assert (tmp_path / "r.h5").stat().st_mtime_ns == mtime
    # the same run made by other code (another fingerprint): refused, not "nothing to do"
    with h5py.File(tmp_path / "r.h5", "r+") as h5:
        h5.attrs["solver_fingerprint"] = "0" * 16
    mtime = (tmp_path / "r.h5").stat().st_mtime_ns
    rc, out, err = call(["run", "two-beam", "--samples", "40", "--n-freq", "25", "--seed", "3",
                         "--F0", "0.72", "-o", "r.h5", "--no-progress"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "other solver code" in err and "--force" in err
    assert "already holds" not in out and (tmp_path / "r.h5").stat().st_mtime_ns == mtime


def _before_third_solve(monkeypatch, action):
    """The ensemble's ``hbm.solve`` with ``action()`` run before its third call (the
    third chunk)."""
    real = hbm.solve
    calls = {"n": 0}

    def wrapped(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            action()
        return real(*a, **k)

    monkeypatch.setattr(ensemble.hbm, "solve", wrapped)


def test_bounds_file_holds_the_bound_peak_as_a_run_does(tmp_path, capsys):
    """``mcfric bounds`` refines the upper bound's peak as a run does: printed, written to
    ``bounds/`` (``peak_upper*``), printed again by ``mcfric info``; with ``[peaks]
    enabled = false`` neither."""
    out = tmp_path / "b.h5"
    rc, text, _ = call(["bounds", "two-beam", "--n-freq", "60", "-o", str(out),
                        "--no-figure", "--no-certify"], capsys)
    assert rc == 0
    line = next(x for x in text.splitlines() if x.startswith("bound peak:"))
    with h5py.File(out) as h:
        a = dict(h["bounds"].attrs)
        f, upper = h["frequency"][...], h["bounds/upper"][...]
    k = int(np.argmax(upper))
    # between the grid neighbours of the largest grid value, and not below it
    assert f[k - 1] <= a["peak_upper_frequency"] <= f[k + 1]
    assert a["peak_upper"] >= upper[k] and a["peak_upper_refined"] == 1
    assert f"searched upper bound {a['peak_upper']:.4g} m at " in line and "(refined)" in line
    rc, info, _ = call(["info", str(out)], capsys)
    assert rc == 0 and line in info.splitlines()
    # a bounds file holds no members: info says so rather than '0 of 0 points'
    assert "sampling:    none (a bounds file: no members)" in info
    assert "converged:" not in info and "metric:      displacement m\n" in info
    # verify says it is a bounds file first, not "needs --member" and then that
    for extra in ([], ["--member", "0"]):
        rc, _, err = call(["verify", str(out), "--f", "60"] + extra, capsys)
        assert rc == 2 and "no members (a bounds file)" in err, err
    # what wrote it, as a run's file says (versions and time)
    with h5py.File(out) as h:
        root = dict(h.attrs)
    assert root["numpy_version"] == np.__version__ and "created_utc" in root
    assert f"numpy {np.__version__}, HDF5 " in info and root["created_utc"] in info
    # a run of the same configuration stores the same peak
    rc, _, _ = call(["run", "two-beam", "--n-freq", "60", "--samples", "4", "--no-certify",
                     "-o", str(tmp_path / "r.h5"), "--no-progress", "--no-figure"], capsys)
    with h5py.File(tmp_path / "r.h5") as h:
        assert rc == 0 and {k: h["bounds"].attrs[k] for k in a if k.startswith("peak_")} == \
            {k: v for k, v in a.items() if k.startswith("peak_")}
    (tmp_path / "c.toml").write_text('[model]\npreset = "two-beam"\n[frequency]\nn = 60\n'
                                     '[peaks]\nenabled = false\n[bounds]\ncertify = false\n')
    rc, text, _ = call(["bounds", str(tmp_path / "c.toml"), "-o", str(tmp_path / "c.h5"),
                        "--no-figure"], capsys)
    assert rc == 0 and "bound peak:" not in text
    with h5py.File(tmp_path / "c.h5") as h:
        assert "peak_upper" not in h["bounds"].attrs
    rc, info, _ = call(["info", str(tmp_path / "c.h5")], capsys)
    assert rc == 0 and "bound peak:" not in info


def test_certified_bound_near_the_peak_is_printed_stored_and_drawn(tmp_path, capsys):
    """Certified bounds: ``mcfric bounds`` prints, under the ``bound peak:`` line, the
    worst case on the sub-grid around the peak from the stored ``peak_upper_certified*``
    and ``peak_upper_witness*``; ``mcfric info`` prints the same lines, a run of the same
    configuration stores and prints the same, and the figure marks it."""
    out = tmp_path / "b.h5"
    grid = ["two-beam", "--n-freq", "40", "--f-max", "25"]
    rc, text, _ = call(["bounds", *grid, "-o", str(out)], capsys)
    assert rc == 0
    lines = text.splitlines()
    k = next(i for i, x in enumerate(lines) if x.startswith("bound peak:"))
    line = lines[k + 1]
    with h5py.File(out) as h:
        a = dict(h["bounds"].attrs)
        grid_max = float(np.max(h["bounds/upper_certified"][...]))
    assert a["peak_upper_witness"] <= a["peak_upper_certified"]
    assert line.startswith("             certified: at its frequency and a sub-grid ")
    assert (f"(only there), the worst case is at least {a['peak_upper_witness']:.4g} m "
            f"(attained by a witness at {a['peak_upper_witness_frequency']:.6g} Hz) and at "
            f"most {a['peak_upper_certified']:.4g} m (certified)") in line
    assert f"the grid's largest certified value anywhere: {grid_max:.4g} m at " in line
    rc, info, _ = call(["info", str(out)], capsys)
    heads = ("bound peak:", "             certified: ")
    assert rc == 0 and lines[k:k + 2] == [x for x in info.splitlines() if x.startswith(heads)]
    assert plot.results_figure(out, tmp_path / "b.png")["bound_peaks"] == ["searched",
                                                                            "certified"]
    rc, text, _ = call(["run", *grid, "--samples", "4", "-o", str(tmp_path / "r.h5"),
                        "--no-progress", "--no-figure"], capsys)
    assert rc == 0 and line in text.splitlines()
    with h5py.File(tmp_path / "r.h5") as h:
        assert {k: h["bounds"].attrs[k] for k in a if k.startswith("peak_")} == \
            {k: v for k, v in a.items() if k.startswith("peak_")}


def test_no_progress_silences_the_certification_bars(tmp_path, monkeypatch, capsys):
    """``--no-progress`` of ``mcfric bounds`` and ``mcfric run`` turns off the
    certification's bars (splitting the box, second-order relaxations); without it they
    show on a terminal only (tqdm's ``disable=None``)."""
    import tqdm

    bars = []

    class Recorder(tqdm.tqdm):
        def __init__(self, *a, **k):
            bars.append((k.get("desc"), k.get("disable")))
            super().__init__(*a, **k)

    monkeypatch.setattr(tqdm, "tqdm", Recorder)
    # five frequencies across the first resonance of the rig: both long stages run there
    grid = ["eight-beam", "--f-min", "16.1", "--f-max", "16.5", "--n-freq", "5",
            "--no-figure"]
    for argv, disable in ((["bounds", *grid, "-o", str(tmp_path / "b.h5")], None),
                          (["bounds", *grid, "-o", str(tmp_path / "c.h5"), "--no-progress"],
                           True),
                          (["run", *grid, "--samples", "2", "-o", str(tmp_path / "r.h5"),
                            "--no-progress"], True)):
        bars.clear()
        rc, _, err = call(argv, capsys)
        names = {d for d, _ in bars}
        assert rc == 0, err
        assert {"splitting the box (upper)", "second-order relaxations"} <= names, argv
        # the grid's certification first; the short certification of the sub-grid
        # around the bound's peak after it never shows bars
        assert [x for _, x in bars[:2]] == [disable] * 2, (argv, bars)
        assert all(x is True for _, x in bars[2:]), (argv, bars)


@pytest.mark.parametrize("signal_", ["raise KeyboardInterrupt",
                                     "os.kill(os.getpid(), signal.SIGTERM)",
                                     "os.kill(os.getpid(), signal.SIGHUP)"])
def test_ctrl_c_while_the_libraries_load_is_one_line(tmp_path, signal_):
    """Ctrl-C, SIGTERM or SIGHUP while numpy, numba and the commands load (about the
    first second of a command) is one line and exit 130, as later: the package loads
    none of them before the entry point runs, which takes the signals first (before, a
    SIGINT 0.01-1.07 s after the start printed Python's 26-line traceback, a SIGTERM
    before 1.2 s ended the process with no word, exit -15). Simulated by an import hook
    that signals when numpy is first imported."""
    script = "\n".join([
        "import os, signal, sys",
        "class Interrupt:",
        "    def find_spec(self, name, path=None, target=None):",
        "        if name == 'numpy':",
        "            " + signal_,
        "sys.meta_path.insert(0, Interrupt())",
        "from mcfric.cli import main",
        "sys.exit(main(['info', 'nothing.h5']))"])
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       cwd=tmp_path, timeout=120)
    assert (p.returncode, p.stderr, p.stdout) == (130, "mcfric: interrupted\n", "")
    assert list(tmp_path.iterdir()) == []


def test_a_finished_command_ends_with_its_exit_code_whatever_signal_comes_after():
    """Called as the program, the entry point ignores Ctrl-C, SIGTERM and SIGHUP once the
    command has returned: a signal while the interpreter shuts down (up to a second)
    ended a finished ``mcfric bounds`` as killed (exit -2, no word)."""
    script = "\n".join([
        "import os, signal, sys",
        "sys.argv = ['mcfric', 'config', 'two-beam']",
        "from mcfric.cli import main",
        "rc = main()",
        "for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):",
        "    os.kill(os.getpid(), s)",
        "print('exit', rc)"])
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0 and p.stdout.endswith("exit 0\n") and p.stderr == ""


def test_an_interrupt_after_the_bounds_file_is_written_says_it_is_complete(
        tmp_path, monkeypatch, capsys):
    """``mcfric bounds`` cut short while it draws the figure: the file is whole (renamed
    into place), and the message says so, as ``mcfric run``'s does (it said only
    "interrupted")."""
    from mcfric.bounds import read_bounds

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plot, "results_figure", stop)
    out = tmp_path / "b.h5"
    rc, text, err = call(["bounds", "two-beam", "--n-freq", "20", "--no-certify", "-o",
                          str(out), "--no-progress"], capsys)
    assert rc == 130 and err.strip() == (f"interrupted: {out} is complete; the lines or the "
                                         f"figure after it were cut short (`mcfric info "
                                         f"{out}`, `mcfric plot {out}`)")
    assert read_bounds(out).upper.shape == (20,) and f"bounds: {out}" in text
    # cut short before the file is written: the plain message, nothing left
    from mcfric import bounds as bounds_api

    monkeypatch.setattr(bounds_api, "write_bounds_file", stop)
    (tmp_path / "c").mkdir()
    rc, _, err = call(["bounds", "two-beam", "--n-freq", "20", "--no-certify", "-o",
                       str(tmp_path / "c" / "b.h5"), "--no-progress"], capsys)
    assert rc == 130 and err.strip() == "mcfric: interrupted"
    assert list((tmp_path / "c").iterdir()) == []


def test_the_public_names_load_on_first_use():
    """``import mcfric`` loads no solver module (the entry point's Ctrl-C above); every
    name of ``__all__`` is there on first use, and ``dir`` lists them."""
    script = ("import sys, mcfric; print(sorted({'numpy', 'numba', 'h5py'} & "
              "set(sys.modules)))")
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=120)
    assert p.stdout == "[]\n", p.stderr
    import mcfric

    for name in mcfric.__all__:
        assert getattr(mcfric, name) is not None and name in dir(mcfric)
    assert mcfric.preset("two-beam").n_beams == 2
    # submodules too, as when __init__ imported them
    assert mcfric.ensemble.run is ensemble.run and mcfric.hbm.solve is mcfric.solve
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        mcfric.nothing


def test_info_of_a_partial_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)

    def stop():
        raise KeyboardInterrupt

    _before_third_solve(monkeypatch, stop)
    rc, _, err = call(["run", "two-beam", "--samples", "50", "--n-freq", "10", "--chunk", "10",
                       "-o", "p.h5", "--no-progress"], capsys)
    assert rc == 130 and "20 of 50 samples saved" in err and "--resume" in err
    assert not (tmp_path / "p.h5").exists() and not (tmp_path / "p.png").exists()
    rc, out, _ = call(["info", "p.h5"], capsys)
    assert rc == 0 and "INCOMPLETE: 20 of 50 samples done" in out


def test_a_partial_beside_a_complete_file_is_named_and_resumable(tmp_path, monkeypatch,
                                                                  capsys):
    """A --force run cut short leaves ``FILE.partial`` beside the complete ``FILE``: a run
    of FILE's configuration says so and leaves both as they are; --resume continues the
    run that was to replace FILE, also where FILE holds the same run by other code."""
    monkeypatch.chdir(tmp_path)
    grid = ["--samples", "30", "--n-freq", "8", "--chunk", "10", "--no-progress",
            "--no-figure", "--no-certify", "-o", "f.h5"]
    assert call(["run", "two-beam", "--seed", "1", *grid], capsys)[0] == 0

    def stop():
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        _before_third_solve(m, stop)
        rc, _, err = call(["run", "two-beam", "--seed", "2", "--force", *grid], capsys)
    assert rc == 130 and "20 of 30 samples saved" in err
    first = (tmp_path / "f.h5").read_bytes()
    rc, out, _ = call(["run", "two-beam", "--seed", "1", *grid], capsys)
    assert rc == 0 and "already holds this run" in out
    note = next(x for x in out.splitlines() if x.startswith("note: f.h5.partial"))
    assert note.startswith("note: f.h5.partial beside it is an interrupted run of another "
                           "configuration (sampling.seed = 2 there, 1 here; 20 of 30 "
                           "samples)") and "--resume` continues it" in note, note
    assert (tmp_path / "f.h5").read_bytes() == first
    # a partial of other code: --resume would refuse it, the note does not offer it
    with h5py.File("f.h5.partial", "r+") as h:
        mine, h.attrs["solver_fingerprint"] = h.attrs["solver_fingerprint"], "0" * 16
    rc, out, _ = call(["run", "two-beam", "--seed", "1", *grid], capsys)
    assert "made by other solver code or libraries, it cannot be continued here" in out
    assert "--resume` continues" not in out
    with h5py.File("f.h5.partial", "r+") as h:
        h.attrs["solver_fingerprint"] = mine
    # an interrupted copy of the same run is called that
    rc, out, _ = call(["run", "two-beam", "--seed", "2", *grid, "--resume"], capsys)
    assert rc == 0 and "already holds" not in out and not (tmp_path / "f.h5.partial").exists()
    with h5py.File("f.h5") as h:
        assert h.attrs["complete"] == 1
    shutil.copy("f.h5", "g.h5")
    with monkeypatch.context() as m:
        _before_third_solve(m, stop)
        assert call(["run", "two-beam", "--seed", "2", "--force", *grid], capsys)[0] == 130
    rc, out, _ = call(["run", "two-beam", "--seed", "2", *grid], capsys)
    assert rc == 0 and "already holds this run" in out
    assert "f.h5.partial beside it is an interrupted copy of this run (20 of 30" in out
    # FILE of the same run made by other code: --resume continues the recomputation
    with h5py.File("f.h5", "r+") as h:
        h.attrs["solver_fingerprint"] = "0" * 16
    rc, _, err = call(["run", "two-beam", "--seed", "2", *grid], capsys)
    assert rc == 2 and "--resume to continue f.h5.partial" in err, err
    rc, out, err = call(["run", "two-beam", "--seed", "2", *grid, "--resume"], capsys)
    assert rc == 0 and "samples: 30 of 30" in out, err
    assert not (tmp_path / "f.h5.partial").exists()
    with h5py.File("f.h5") as h, h5py.File("g.h5") as g:
        assert h.attrs["solver_fingerprint"] == g.attrs["solver_fingerprint"]
        assert np.array_equal(h["metric"][...], g["metric"][...])


def test_a_stop_signal_dropped_while_compiling_still_stops_the_run(tmp_path, monkeypatch,
                                                                    capsys):
    """A SIGTERM whose KeyboardInterrupt was raised inside a ctypes callback (numba
    compiling) is printed and dropped there; the handler's note stops the run before
    its next chunk: exit 130, resumable, as for a delivered one."""
    import signal

    monkeypatch.chdir(tmp_path)

    def dropped():
        try:
            signal.raise_signal(signal.SIGTERM)
        except KeyboardInterrupt:
            pass                    # what the ctypes callback does with it

    # in the main thread, as where numba compiles there (the chunks' solves run on a
    # thread of their own, whose signals reach the main thread's wait)
    real, calls = ensemble.interruptible, {"n": 0}

    def wrapped(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            dropped()
        return real(*a, **k)

    monkeypatch.setattr(ensemble, "interruptible", wrapped)
    rc, _, err = call(["run", "two-beam", "--samples", "50", "--n-freq", "10", "--chunk", "10",
                       "-o", "p.h5", "--no-progress", "--no-certify"], capsys)
    assert rc == 130 and "20 of 50 samples saved" in err and "--resume" in err
    assert stop_signals.RECEIVED == ["SIGTERM"]


def test_a_stop_signal_dropped_in_a_weakref_callback_stops_the_bounds(tmp_path, monkeypatch,
                                                                      capsys):
    """A SIGTERM whose KeyboardInterrupt is raised inside a weak reference's callback is
    dropped there by Python (before: the traceback printed, and `mcfric bounds` ran on to
    exit 0). The note stops the work at its next step: one line, exit 130, no file, no
    traceback."""
    import signal
    import weakref

    from mcfric import bounds

    monkeypatch.chdir(tmp_path)
    real = bounds.from_spec

    class Thing:
        pass

    def from_spec(*a, **k):
        thing = Thing()
        ref = weakref.ref(thing, lambda _: signal.raise_signal(signal.SIGTERM))
        del thing                   # the handler runs inside the callback
        assert ref() is None
        return real(*a, **k)

    monkeypatch.setattr(bounds, "from_spec", from_spec)
    rc, _, err = call(["bounds", "two-beam", "--n-freq", "10", "-o", "b.h5", "--no-progress",
                       "--no-figure"], capsys)
    assert rc == 130 and err.strip() == "mcfric: interrupted", err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, kind", [
    (["run", "two-beam", "--samples", "3_0"], "int"),          # int() reads 30
    (["run", "two-beam", "--n-freq", "\u0663"], "int"),        # Arabic-Indic 3
    (["run", "two-beam", "--seed", "1_000"], "int"),
    (["hbm", "two-beam", "--mu0", "1_0"], "float"),           # float() reads 10.0
    (["hbm", "two-beam", "--F0", "\u0661.5"], "float"),
    (["verify", "two-beam", "--f", "3_0"], "frequency"),
    (["bounds", "two-beam", "--F-lim", "0_5"], "F-lim"),
])
def test_numbers_in_flags_are_ascii_decimals(argv, kind, tmp_path, monkeypatch, capsys):
    """Python's int() and float() take digit separators and other scripts' digits: a
    typo ran silently as another number. One line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(argv + ["-o", "x.csv" if argv[0] in ("hbm", "verify") else "x.h5"],
                        capsys)
    assert rc == 2 and kind in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


def test_a_compilation_is_announced_once_on_a_terminal_only(monkeypatch):
    """The first command after an install compiles for minutes (a ring's multi-harmonic
    kernel about four) in silence: on a terminal one line says so, once per process;
    a log or a pipe gets nothing, nor does a warm run (no compile event)."""
    import io

    from mcfric.cli import compiling

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    def fresh():            # a new function each time: numba compiles it (no cache)
        return numba.njit(lambda x: x + 1)

    monkeypatch.setattr(compiling, "_SAID", compiling.threading.Event())
    pipe, term = io.StringIO(), Terminal()
    undo = compiling.announce_compilation(pipe)
    fresh()(1)
    undo()
    assert pipe.getvalue() == ""
    undo = compiling.announce_compilation(term)
    try:
        fresh()(1)
        fresh()(2.0)
        fresh()(1)          # compiled already: no event
    finally:
        undo()
    assert term.getvalue() == compiling.MESSAGE + "\n"
    monkeypatch.setattr(compiling, "_SAID", compiling.threading.Event())
    fresh()(3)              # the listener removed: nothing, though not yet said
    assert term.getvalue().count("compiling") == 1


def test_a_caller_gets_its_signal_handlers_back_and_a_fresh_note(tmp_path, monkeypatch,
                                                                  capsys):
    """Called with arguments (a test, a script), the entry point hands SIGTERM and SIGHUP
    back as it found them, and a stop noted by an earlier command does not stop the
    next one."""
    import signal

    monkeypatch.chdir(tmp_path)
    mine = {s: (lambda signum, frame: None) for s in (signal.SIGTERM, signal.SIGHUP)}
    before = {s: signal.signal(s, h) for s, h in mine.items()}
    try:
        stop_signals.RECEIVED[:] = ["SIGTERM"]         # left by an earlier, stopped command
        rc, _, err = call(["run", "two-beam", "--samples", "20", "--n-freq", "5",
                           "-o", "r.h5", "--no-progress", "--no-certify", "--no-figure"],
                          capsys)
        assert rc == 0, err
        assert (tmp_path / "r.h5").exists() and stop_signals.RECEIVED == []
        assert all(signal.getsignal(s) is h for s, h in mine.items())
    finally:
        for s, h in before.items():
            signal.signal(s, h)


@pytest.mark.parametrize("limit, admitted", [("k_max = 15.0", "none"),   # kN/m for N/m
                                             ("F_lim = 0.2", "some")])
def test_members_outside_the_bounds_constraints_are_named_and_left_out(tmp_path, capsys,
                                                                        limit, admitted):
    """Bounds over a box narrower than the sampling hold for the members inside it: those
    are checked (none may be outside), the others are counted and left out, said up front;
    no "please report" for a limit the user gave."""
    cfg = tmp_path / "k.toml"
    cfg.write_text(f'[model]\npreset = "two-beam"\n[bounds]\n{limit}\n')
    out = tmp_path / "k.h5"
    rc, text, _ = call(["run", str(cfg), "--samples", "40", "--n-freq", "60", "-o", str(out),
                        "--no-progress", "--no-figure", "--first-order"], capsys)
    assert rc == 0 and "please report" not in text
    assert "note: the bounds' constraints leave out members" in text
    assert limit.split(" = ")[0] in text.split("note:")[1].splitlines()[0]
    with h5py.File(out) as h:
        mu0, kc, N0 = h["mu0"][...], h["kc"][...], h["N0"][...]
        a = h["bounds"].attrs
        k_re, k_im, F_lim = float(a["k_max_re"]), float(a["k_max_im"]), float(a["F_lim"])
    inside = ((kc <= k_re) & (kc / np.pi <= k_im) & (4 / np.pi * mu0 * N0 <= F_lim)).all(-1)
    left = int(np.count_nonzero(~inside))
    assert (left == 40) if admitted == "none" else (0 < left < 40)
    m = re.search(r"bounds check: (\d+) of 40 members have friction outside", text)
    assert m and int(m.group(1)) == left
    m = re.search(r"searched bounds check: (\d+) of ([\d,]+) converged", text)
    assert m.group(1) == "0" and int(m.group(2).replace(",", "")) <= 60 * (40 - left)
    assert re.search(r"certified bounds check: 0 outside", text)


def test_the_bounds_note_only_where_a_limit_falls_short_of_the_run_computing_them(tmp_path,
                                                                                 capsys):
    """No note for an unbounded distribution's tail (the check after the run counts any
    member left out), nor for a complete file, which keeps the bounds it was made with."""
    cfg = tmp_path / "n.toml"
    cfg.write_text('[model]\npreset = "two-beam"\n[sampling]\n'
                   'kc = {dist = "normal", mean = 6000.0, std = 500.0}\n'
                   '[bounds]\nk_max = 9000.0\nF_lim = "none"\n')
    out = tmp_path / "n.h5"
    argv = ["run", str(cfg), "--samples", "4", "--n-freq", "20", "-o", str(out),
            "--no-progress", "--no-figure", "--no-certify"]
    rc, text, _ = call(argv, capsys)
    assert rc == 0 and "note: the bounds' constraints" not in text
    assert "members have friction outside" not in text
    cfg.write_text(cfg.read_text().replace("k_max = 9000.0", "k_max = 15.0"))
    rc, text, _ = call(argv, capsys)
    assert rc == 0 and "already holds this run" in text
    assert "note: the bounds' constraints" not in text


@pytest.mark.parametrize("argv, close", [(["runn", "two-beam"], "run"), (["inf", "x.h5"], "info"),
                                         (["bound"], "bounds"), (["verfy"], "verify")])
def test_a_misspelt_command_is_named(argv, close, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(argv, capsys)
    assert rc == 2 and out == "" and err.count("\n") == 1
    assert f"unknown command {argv[0]!r} (did you mean {close!r}?" in err
    assert list(tmp_path.iterdir()) == []
    # a file's name is no command: its absence is said as before
    rc, _, err = call(["plot.toml"], capsys)
    assert rc == 2 and "unknown command" not in err and "plot.toml" in err


@pytest.mark.parametrize("cmd", ["hbm", "run", "plot"])
def test_an_unknown_option_points_to_its_commands_help(cmd, capsys):
    rc, _, err = call([cmd] + (["x.h5"] if cmd == "plot" else []) + ["--bogus"], capsys)
    assert rc == 2 and f"unrecognized arguments: --bogus (see `mcfric {cmd} --help`)" in err


@pytest.mark.parametrize("argv, option", [
    (["run", "--nfreq", "10"], "--n-freq"), (["run", "--f0", "0.3"], "--F0"),
    (["run", "--n_freq=10"], "--n-freq"), (["hbm", "--harmonic", "3"], "--harmonics"),
    (["plot", "r.h5", "--memebr", "3"], "--member")])
def test_a_mistyped_option_is_named_with_the_one_meant(argv, option, tmp_path, monkeypatch,
                                                       capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(argv, capsys)
    assert rc == 2 and out == "" and err.count("\n") == 1
    assert f"(did you mean {option}? see `mcfric {argv[0]} --help`)" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, hint", [
    (["run", "--N0", "0.5"], "--N0 is an option of `mcfric hbm` and `mcfric verify`"),
    (["run", "--k-max", "3"], "--k-max is an option of `mcfric bounds`"),
    (["plot", "r.h5", "--no-peaks"], "--no-peaks is an option of `mcfric run`")])
def test_another_commands_option_is_named_with_its_command(argv, hint, capsys):
    # by closeness alone, --N0 was "did you mean --F0?" (the drive, not the preload)
    rc, out, err = call(argv, capsys)
    assert rc == 2 and out == "" and err.count("\n") == 1
    assert f"({hint}; see `mcfric {argv[0]} --help`)" in err, err


@pytest.mark.parametrize("argv, message", [
    (["hbm", "--F0", "-inf"], "--F0: expected a finite number"),
    (["hbm", "--F0", "-1e-3"], "got -0.001"),
    (["hbm", "--mu0", "-nan"], "--mu0: expected a finite number >= 0, got nan"),
    (["verify", "--f", "-1e-3"], "--f: frequencies must be > 0 Hz"),
    (["verify", "--f", "-1e-3", "10"], "--f: frequencies must be > 0 Hz"),
    (["verify", "--f", "10", "-1e-3"], "--f: frequencies must be > 0 Hz")])
def test_a_negative_value_in_exponent_form_reaches_its_options_check(argv, message, tmp_path,
                                                                     monkeypatch, capsys):
    # argparse alone took "-1e-3" and "-inf" for options ("expected one argument", or
    # "expected at least one argument" for --f)
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(argv, capsys)
    assert rc == 2 and out == "" and err.count("\n") == 1
    assert message in err and "one argument" not in err
    assert list(tmp_path.iterdir()) == []


def test_no_arguments_runs_the_embedded_default(tmp_path, monkeypatch, capsys):
    seen = {}

    def fake_run(cfg, path, **kw):
        seen.update(cfg=cfg, path=path, **kw)
        # a new run, whose bounds' summary was printed as they were computed
        return ensemble.Summary(Path(path), cfg.samples, 1000, cfg.samples, cfg.samples, 0,
                                1.0, 0.9, True, bounds_computed=True)

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(ensemble, "run", fake_run)
    monkeypatch.setattr(plot, "results_figure", lambda h5, png, **kw: seen.update(png=png))
    from mcfric.bounds import members_check
    monkeypatch.setattr(members_check, "check_members", lambda path: None)   # no file written
    rc, out, _ = call([], capsys)
    assert rc == 0
    cfg = seen["cfg"]
    assert cfg.data == config.load(None).data
    m = cfg.model()
    assert (m.name, m.n_beams, m.excitation.F0, cfg.samples) == ("eight-beam", 8, 1.1, 2000)
    assert (cfg["frequency"]["f_min"], cfg["frequency"]["f_max"]) == (10.0, 150.0)
    assert seen["path"] == Path("mcfric-results/default.h5")
    assert seen["png"] == Path("mcfric-results/default.png")
    assert "results: mcfric-results/default.h5" in out
    assert "figure: mcfric-results/default.png" in out
    assert seen["resume"] is False and seen["force"] is False


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


def test_hbm_csv_and_png(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = call(["hbm", "eight-beam", "--mu0", "0.6", "--kc", "5000", "--N0", "0.4",
                         "--F0", "0.25", "--n-freq", "60", "-o", "h.csv"], capsys)
    assert rc == 0, err
    header, t = read_csv(tmp_path / "h.csv")
    assert header == (["frequency_hz"] + [f"abs_y{b}_m" for b in range(1, 9)]
                      + ["metric_m", "converged"] + [f"s{j}" for j in range(1, 8)])
    assert t.shape == (60, 1 + 8 + 2 + 7)
    f = np.linspace(10, 150, 60)
    np.testing.assert_allclose(t[:, 0], f, rtol=1e-9)
    r = hbm.solve(config.load("eight-beam", {"excitation.F0": (0.25, "")}).model(), f,
                  0.6, 5000.0, 0.4)
    np.testing.assert_allclose(t[:, 1:9], np.abs(r.response[0]), rtol=1e-9)
    np.testing.assert_allclose(t[:, 9], t[:, 1:9].max(axis=1), rtol=1e-9)
    np.testing.assert_array_equal(t[:, 10], 1.0)
    np.testing.assert_allclose(t[:, 11:], r.s[0], rtol=1e-9)
    assert "not converged: 0 of 60 points" in out
    assert (tmp_path / "h.png").stat().st_size > 10000


def test_hbm_figure_draws_beams_and_metric_in_one_unit(tmp_path, monkeypatch, capsys):
    """With metric.quantity = acceleration the beams were drawn in m beside M in m/s^2
    on one unlabelled axis: the metric is the largest of the beams drawn."""
    from mcfric import plot

    seen = {}
    monkeypatch.setattr(plot, "hbm_figure", lambda *a, **k: seen.update(args=a, kw=k))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.toml").write_text('model.preset = "two-beam"\n'
                                     'metric.quantity = "acceleration"\n')
    rc, _, err = call(["hbm", "c.toml", "--n-freq", "40"], capsys)
    assert rc == 0, err
    f, amp, metric, conv = seen["args"][:4]
    assert conv.all()
    np.testing.assert_allclose(metric, amp.max(axis=1), rtol=1e-12)
    _, t = read_csv(tmp_path / "mcfric-results" / "hbm-c.csv")
    np.testing.assert_allclose(amp, t[:, 1:3] * (2 * np.pi * f[:, None]) ** 2, rtol=1e-9)
    assert seen["kw"]["ylabel"] == "acceleration amplitude at the output [m/s^2]"


def test_hbm_says_when_beams_differ_or_mistuning_is_not_applied(tmp_path, monkeypatch,
                                                                  capsys):
    """The name is free text (often the preset's): a beam with its own table, and a
    mistuning hbm does not draw, are said on the header line."""
    monkeypatch.chdir(tmp_path)
    base = 'model.preset = "eight-beam"\n'
    for text, said in (
            ("", None),
            ("[[model.beam]]\nbeam = 2\nfreq_hz = [16.9, 108.0]\n",
             "; beam 2 with a modal table unlike beam 1's"),
            ("[[model.beam]]\nbeam = 1\nfreq_hz = [16.9, 108.0]\n",
             "; beams 2, 3, 4, 5, 6, 7, 8 with a modal table unlike beam 1's"),
            ("sampling.mistuning = 0.05\n",
             "; sampling.mistuning not applied (the nominal tables)")):
        (tmp_path / "c.toml").write_text(base + text)
        rc, out, err = call(["hbm", "c.toml", "--n-freq", "3", "--no-figure"], capsys)
        assert rc == 0, err
        head = out.splitlines()[0]
        assert head.endswith("single-harmonic" if said is None else said), head


def test_hbm_counts_non_converged_points(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    # three Newton iterations per attempt: some points cannot converge
    (tmp_path / "c.toml").write_text('model.preset = "eight-beam"\nsolver.max_iter = 3\n'
                                     'solver.tol = 1e-14\n')
    rc, out, _ = call(["hbm", "c.toml", "--n-freq", "300", "--mu0", "0.1", "--kc", "6000"],
                      capsys)
    assert rc == 0
    _, t = read_csv(tmp_path / "mcfric-results" / "hbm-c.csv")
    bad = int(np.count_nonzero(t[:, 10] == 0))
    assert bad > 0
    assert f"not converged: {bad} of 300 points" in out
    assert np.all(np.isnan(t[t[:, 10] == 0, 1:10]))
    assert (tmp_path / "mcfric-results" / "hbm-c.png").exists()


def test_a_complete_file_says_when_it_keeps_other_bounds(tmp_path, capsys):
    """[bounds] is not part of a run's identity: a file made without bounds (or with
    other settings) is 'already complete' for a configuration with them, and the run
    says that the bounds asked for were not computed."""
    out = tmp_path / "a.h5"
    base = ["run", "two-beam", "--samples", "4", "--n-freq", "10", "-o", str(out),
            "--no-progress", "--no-figure"]
    assert cli.main(base + ["--no-bounds"]) == 0
    capsys.readouterr()
    assert cli.main(base) == 0
    text = capsys.readouterr().out
    assert "already holds this run" in text
    assert f"note: {out} has no bounds (the session that created it had [bounds] " \
           f"enabled = false); `mcfric bounds` computes" in text
    assert cli.main(base + ["--no-bounds"]) == 0                  # the same [bounds]: no note
    assert "note:" not in capsys.readouterr().out


def test_a_mistuned_run_does_not_call_members_outside_the_bounds_a_fault(tmp_path, capsys):
    """The bounds are the nominal rig's: mistuned members outside them are expected
    ('please report' before)."""
    toml = tmp_path / "m.toml"
    toml.write_text('[model]\npreset = "two-beam"\n[sampling]\nsamples = 20\n'
                    'mistuning = 0.1\n[frequency]\nn = 40\n')
    out = tmp_path / "m.h5"
    assert cli.main(["run", str(toml), "-o", str(out), "--no-certify", "--no-progress",
                     "--no-figure"]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if x.startswith("searched bounds check"))
    n = int(line.split(": ")[1].split(" of ")[0])
    assert n > 0, line                                   # mistuned members do leave
    assert "the members mistuned: not a fault" in line and "please report" not in text


def test_points_where_the_bounds_search_failed_are_not_called_outside(tmp_path, capsys,
                                                                      monkeypatch):
    """A frequency whose searched (or certified) bounds failed (NaN, set here by hand on
    the file's bounds as the check reads them) has nothing to check against: its points
    are counted apart, not as points the search missed ('please report' before) or a
    broken certificate."""
    import mcfric.bounds

    real = mcfric.bounds.read_bounds

    def failed_at_three(path):
        B = real(path)
        B.upper[[2, 5]] = np.nan
        B.lower[7] = np.nan
        B.certificate.upper[[2, 5]] = np.nan
        return B

    monkeypatch.setattr(mcfric.bounds, "read_bounds", failed_at_three)
    monkeypatch.setattr(mcfric.bounds.members_check, "read_bounds", failed_at_three)
    out = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "5", "--n-freq", "10",
                     "--no-progress", "--no-figure", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if x.startswith("searched bounds check"))
    assert line.startswith("searched bounds check: 0 of 35 converged member points"), line
    assert "; 15 at the frequencies where the search failed" in line
    line = next(x for x in text.splitlines() if x.startswith("certified bounds check"))
    assert line.startswith("certified bounds check: 0 outside"), line
    assert "; 10 at frequencies without certified bounds (a failed search)" in line
    assert "please report" not in text and "broken" not in text
    # the bound's peak may lie where the search failed: its line says so
    import h5py

    from mcfric.peaks import bound_peak, bound_peak_lines
    assert "the search failed" not in " ".join(bound_peak_lines(bound_peak(out), "m"))
    with h5py.File(out, "r+") as h5:
        up, lo = h5["bounds/upper"], h5["bounds/lower"]
        up[[2, 5]] = np.nan
        lo[7] = np.nan                      # the lower bound's failure hides no peak
    assert ("; the search failed at 2 frequencies, where the bound's peak may lie"
            in bound_peak_lines(bound_peak(out), "m")[0])


def test_verify_knows_a_results_file_by_its_content(tmp_path, capsys):
    """run writes any -o name; verify took only *.h5 as a results file."""
    out = tmp_path / "out.H5"
    assert cli.main(["run", "two-beam", "--samples", "2", "--n-freq", "10", "--no-bounds",
                     "--no-progress", "--no-figure", "-o", str(out)]) == 0
    capsys.readouterr()
    rc = cli.main(["verify", str(out), "--member", "0", "--f", "35", "--harmonics", "3",
                   "--no-figure", "--no-progress", "-o", str(tmp_path / "v.csv")])
    assert rc == 0, capsys.readouterr().err


def test_verify_of_a_file_checks_its_default_output_too(tmp_path, capsys, monkeypatch):
    """`verify FILE` without -o wrote mcfric-results/verify-NAME.csv unchecked: an HDF5
    file there was overwritten."""
    monkeypatch.chdir(tmp_path)
    res = tmp_path / "good.h5"
    assert cli.main(["run", "two-beam", "--samples", "2", "--n-freq", "10", "--no-bounds",
                     "--no-progress", "--no-figure", "-o", str(res)]) == 0
    (tmp_path / "mcfric-results").mkdir()
    clash = tmp_path / "mcfric-results" / "verify-good.csv"
    clash.write_bytes(res.read_bytes())
    capsys.readouterr()
    rc = cli.main(["verify", str(res), "--member", "0", "--f", "35", "--harmonics", "3",
                   "--no-figure", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and "is an HDF5 file" in err, err
    assert clash.read_bytes() == res.read_bytes()


def test_a_refused_run_leaves_no_empty_results_directory(tmp_path, monkeypatch, capsys):
    """A run refused after its default output path was chosen (here: the disk space
    check) made ``mcfric-results/`` and left it empty; it is removed again, and a directory
    that was there before is kept."""
    monkeypatch.chdir(tmp_path)
    rc, _, err = call(["run", "two-beam", "--samples", "1000000000"], capsys)
    assert rc != 0 and "free" in err
    assert not (tmp_path / "mcfric-results").exists()
    (tmp_path / "mcfric-results").mkdir()
    rc, _, _ = call(["run", "two-beam", "--samples", "1000000000"], capsys)
    assert rc != 0 and (tmp_path / "mcfric-results").is_dir()


def test_run_onto_a_bounds_file_says_it_holds_bounds(tmp_path, capsys):
    """A bounds file of the same configuration given to ``run -o`` was "this run, made
    by other solver code ... fingerprint None"; it is named as bounds alone, kept."""
    out = tmp_path / "b.h5"
    grid = ["two-beam", "--n-freq", "20", "-o", str(out)]
    assert call(["bounds", *grid, "--no-figure"], capsys)[0] == 0
    before = out.read_bytes()
    rc, _, err = call(["run", *grid], capsys)
    assert rc == 2 and "holds bounds alone (mcfric bounds), no members" in err
    assert "fingerprint" not in err and out.read_bytes() == before
    # a --force run over it, interrupted, resumes as its message says (it was refused)
    real, calls = hbm.solve, []

    def stop_at_3(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    small = [*grid, "--samples", "40", "--chunk", "8", "--no-figure", "--no-progress"]
    ensemble.hbm.solve = stop_at_3
    try:
        assert call(["run", *small, "--force"], capsys)[0] == 130
    finally:
        ensemble.hbm.solve = real
    assert out.with_name("b.h5.partial").exists()
    rc, text, err = call(["run", *small, "--resume"], capsys)
    assert rc == 0, err
    with h5py.File(out) as h:
        assert int(h.attrs["samples"]) == 40 and h["done"][...].all()


@pytest.mark.parametrize("held", ["out-eo2.png", "out-eo2.h5", "out-eo1.h5.partial"])
def test_every_engine_orders_names_are_checked_before_the_first_order(tmp_path, capsys,
                                                                      monkeypatch, held):
    """A directory holding a later order's figure, results file or partial name: refused
    in one line before any order runs (order 1 ran, and order 2 failed after its work,
    before)."""
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text('[model]\npreset = "disk-24"\n[sampling]\nsamples = 2\n'
                              '[frequency]\nn = 8\n[bounds]\nenabled = false\n'
                              '[excitation]\nengine_orders = [1, 2]\n')
    Path(held).mkdir()
    rc = cli.main(["run", "s.toml", "-o", "out.h5", "--no-progress", "--force"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.endswith(f"{held} is a directory") and "\n" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([held, "s.toml"])


def test_a_sweep_checks_each_orders_figure_beside_another_commands_output(tmp_path, capsys,
                                                                        monkeypatch):
    """An engine-order sweep draws out-eo1.png, out-eo2.png, never out.png: an hbm's
    out.csv and out.png beside -o out.h5 refused it (its escape, out.h5 existing, never
    came), and an hbm's out-eo2.png beside out-eo2.csv would have been replaced."""
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text('[model]\npreset = "disk-24"\n[sampling]\nsamples = 2\n'
                              '[frequency]\nn = 8\n[bounds]\nenabled = false\n'
                              '[excitation]\nengine_orders = [1, 2]\n')
    for name in ("out-eo2.csv", "out-eo2.png"):
        Path(name).write_text("an hbm's\n")
    rc = cli.main(["run", "s.toml", "-o", "out.h5", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "engine order 2: out-eo2.png exists beside out-eo2.csv" in err, err
    assert "\n" not in err and Path("out-eo2.png").read_text() == "an hbm's\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out-eo2.csv", "out-eo2.png",
                                                          "s.toml"]
    for name in ("out-eo2.csv", "out-eo2.png"):
        Path(name).unlink()
        Path(name.replace("-eo2", "")).write_text("an hbm's\n")
    rc = cli.main(["run", "s.toml", "-o", "out.h5", "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    assert Path("out-eo1.png").exists() and Path("out.png").read_text() == "an hbm's\n"


def test_a_default_output_directory_that_cannot_be_made_is_one_line(tmp_path, capsys,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("mcfric-results").write_text("a file, not a directory\n")
    rc = cli.main(["run", "two-beam", "--samples", "2", "--n-freq", "8", "--no-bounds",
                   "--no-figure", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == ("mcfric: error: cannot make the default output directory "
                               "mcfric-results (File exists); give -o FILE"), err
