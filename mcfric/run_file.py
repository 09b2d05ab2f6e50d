"""A run's results file before it is written: what it holds and what it needs.

:func:`layout` gives the file's coordinates, variables and root attributes (among them
the :func:`fingerprint` of the code and machine that decide a result's bits);
:func:`chunk_samples` the samples per chunk; :func:`output_bytes` and
:func:`peak_memory_bytes` its size on disk and the run's in memory, which
:mod:`mcfric.ensemble` checks before any work.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from . import hbm
from .metric import METRIC_UNITS
from .provenance import software_attrs
from .store import allocated_bytes

#: The record dimension of a run's file: one record per member (sample).
RECORD = "sample"
#: Kernel output per chunk when run.chunk = 0 (auto).
CHUNK_TARGET_BYTES = 32 << 20
#: Source files whose change can change a result: a resume across such a change is refused.
FINGERPRINT_FILES = ("core/*.py", "hbm.py", "model.py", "sampling.py", "metric.py",
                     "peaks.py", "indicator.py", "ensemble.py", "run_file.py",
                     "config/configuration.py")


def fingerprint():
    """sha256 of what determines a result's bits: the sources, the numpy, scipy, numba and
    llvmlite versions, and the machine (the CPU features numpy's loops and numba's code
    use; the same instructions on another CPU family can round differently)."""
    global _FINGERPRINT
    if _FINGERPRINT is None:
        import llvmlite
        import numba
        import scipy
        from llvmlite import binding

        h = hashlib.sha256()
        root = Path(__file__).parent
        for pattern in FINGERPRINT_FILES:
            for p in sorted(root.glob(pattern)):
                h.update(p.relative_to(root).as_posix().encode())
                h.update(p.read_bytes())
        h.update(f"numpy {np.__version__} scipy {scipy.__version__} numba {numba.__version__}"
                 f" llvmlite {llvmlite.__version__}".encode())
        h.update(f"cpu {binding.get_host_cpu_name()} {binding.get_host_cpu_features().flatten()}"
                 f" numpy {_numpy_cpu_features()} svml {numba.config.USING_SVML}".encode())
        _FINGERPRINT = h.hexdigest()[:16]
    return _FINGERPRINT


_FINGERPRINT = None


def _numpy_cpu_features():
    """The CPU features numpy's loops dispatch on here (sorted names)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:                              # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    return ",".join(sorted(k for k, v in features.items() if v))


def auto_chunk(spec):
    """Samples per chunk for ``run.chunk = 0``: a power of two giving ~32 MB of output."""
    n_f = len(spec.freq_hz)
    nb, nd = spec.model.n_beams, spec.model.n_dampers
    per_sample = n_f * (16 * nb + 8 * nd + 1 + 2 + 8 + 8 + 1)   # kernel outputs + metric
    if spec.peaks:
        per_sample += spec.peaks.count * (16 * nb + 8 * 4 + 2)
    H = spec.solver.harmonics
    n_h = (H + 1) // 2
    if H > 1:
        per_sample += n_f * nb * 8 * (1 + 2 * n_h * spec.keep_harmonics)
    if spec.mistuned:
        per_sample += n_f * 4 * nb * 16 * (1 + n_h * (H > 1))       # per-sample receptances
    k = max(1, CHUNK_TARGET_BYTES // per_sample)
    if H > 1:
        # a multi-harmonic point costs tens of single-harmonic ones: small chunks keep
        # the progress bar and the checkpoints moving
        k = min(k, 32)
    return int(min(1 << (k.bit_length() - 1), spec.samples))


def chunk_samples(spec):
    """Samples per chunk of a run: ``[run] chunk``, or :func:`auto_chunk` for 0; at most
    the run's samples."""
    return min(spec.samples, spec.execution.chunk or auto_chunk(spec))


def layout(spec):
    """The store layout of a run: coords, variables, root attrs, summary placeholders."""
    model = spec.model
    nb, nd = model.n_beams, model.n_dampers
    a, b = model.dampers
    q = spec.metric.quantity
    coords = {
        "frequency": (spec.freq_hz, {"units": "Hz", "long_name": "excitation frequency"}),
        "beam": (np.arange(1, nb + 1), {"long_name": "beam number (1-based)"}),
        "damper": (np.arange(1, nd + 1),
                   {"long_name": "damper number (1-based); couples beam_a and beam_b",
                    "beam_a": a + 1, "beam_b": b + 1}),
    }
    P = (RECORD, "damper")
    H = spec.solver.harmonics
    # with H > 1 the amplitudes stored are the fundamental's (response_peak: the full
    # period's peak)
    fund = "" if H == 1 else f" of the fundamental (odd harmonics 1..{H} balanced)"
    variables = {
        "metric": ((RECORD, "frequency"), np.float64,
                   {"units": METRIC_UNITS[q],
                    "long_name": f"max over beams of the {q} amplitude{fund} at the output "
                                 f"position; NaN where not converged",
                    "quantity": q, "beams": json.dumps(spec.metric.beams_label)}),
        "converged": ((RECORD, "frequency"), np.bool_,
                      {"long_name": "true where the harmonic balance converged"}),
        "mu0": (P, np.float64, {"units": "1", "long_name": "friction coefficient"}),
        "kc": (P, np.float64, {"units": "N/m", "long_name": "tangential contact stiffness"}),
        "N0": (P, np.float64, {"units": "N", "long_name": "normal preload"}),
    }
    if spec.keep_response and spec.response_format == "amplitude":
        variables = {"amplitude": ((RECORD, "frequency", "beam"), np.float32,
                                   {"units": "m", "long_name":
                                    f"displacement amplitude |X|{fund} at the output "
                                    f"position (float32); NaN where not converged"}),
                     **variables}
    elif spec.keep_response:
        variables = {"response": ((RECORD, "frequency", "beam"), np.complex128,
                                  {"units": "m", "long_name":
                                   f"complex displacement amplitude{fund} at the output "
                                   f"position, x{'' if H == 1 else '1'}(t) = "
                                   f"Re{{X exp(i omega t)}}; NaN where not converged"}),
                     **variables}
    if spec.peaks:
        pk = (RECORD, "peak")
        unit = METRIC_UNITS[q]
        coords["peak"] = (np.arange(1, spec.peaks.count + 1),
                          {"long_name": "peak rank (1 = the member's largest refined peak)"})
        variables.update({
            "peak_metric": (pk, np.float64, {
                "units": unit, "long_name": "the metric at each refined peak, on the branch "
                "continued from below; NaN: the member has no such peak"}),
            "peak_frequency": (pk, np.float64, {"units": "Hz",
                                                "long_name": "frequency of each peak"}),
            "peak_status": (pk, np.int8, {
                "long_name": "0 refined to peaks.rtol, 1 at an end of the band, 2 the grid "
                "value (refinement or the search between grid points failed), -1 no such peak",
                "flag_values": [-1, 0, 1, 2], "flag_meanings": "none refined at_edge grid"}),
            "fold": (pk, np.int8, {
                "long_name": "1: sweeping down around the peak reaches another steady state; "
                "2: so does it, and that branch was not followed to its peak "
                "(peak_metric_down a lower estimate); 0: it does not; -1: not checked",
                "flag_values": [-1, 0, 1, 2], "flag_meanings": "unchecked none fold open"}),
            "peak_metric_down": (pk, np.float64, {
                "units": unit, "long_name": "peak of the branch reached from above (equal "
                "to peak_metric without a fold; a lower estimate where fold is 2)"}),
            "peak_frequency_down": (pk, np.float64, {
                "units": "Hz", "long_name": "frequency of peak_metric_down"}),
        })
        if spec.keep_response:
            variables["peak_response"] = ((RECORD, "peak", "beam"), np.complex128, {
                "units": "m", "long_name": "complex displacement amplitude of every beam "
                "at each refined peak"})
    if spec.solver.harmonics == 1:
        variables["harmonic_indicator"] = ((RECORD, "frequency"), np.float32, {
            "units": "1", "long_name": "estimate of the 3rd and 5th harmonics at the "
            "output relative to the fundamental (max over beams); above "
            f"{hbm.INDICATOR_THRESHOLD:g} one harmonic may not be enough; NaN where not "
            "converged", "threshold": hbm.INDICATOR_THRESHOLD})
    if spec.solver.harmonics > 1:
        variables["from_above"] = ((RECORD, "frequency"), np.bool_, {
            "long_name": "true where the balance converged only from the solution at the "
            "next frequency, sweeping back down: on the branch reached from above"})
        variables["from_rest"] = ((RECORD, "frequency"), np.bool_, {
            "long_name": "true where the balance converged only from rest, raising the "
            "drive at its own frequency (no neighbour's solution converged there): on the "
            "branch connected to rest"})
    if spec.solver.harmonics > 1 and spec.keep_response:
        amp = spec.response_format == "amplitude"
        variables["response_peak"] = ((RECORD, "frequency", "beam"),
                                      np.float32 if amp else np.float64, {
            "units": "m", "long_name": "largest |x(t)| over a period at the output position, "
            "all balanced harmonics together; NaN where not converged"})
        if spec.keep_harmonics:
            n_h = (spec.solver.harmonics + 1) // 2
            coords["harmonic"] = (np.arange(1, 2 * n_h, 2),
                                  {"long_name": "harmonic order (odd)"})
            variables["response_harmonics"] = (
                (RECORD, "frequency", "harmonic", "beam"), np.complex128,
                {"units": "m", "long_name": "complex amplitude of each odd harmonic at the "
                 "output position, x(t) = Re{sum_h X_h exp(i h omega t)}"})
    if spec.mistuned:
        n_modes = model.modal_arrays()[0].shape[1]
        coords["mode"] = (np.arange(1, n_modes + 1), {"long_name": "mode number (1-based)"})
        variables["modal_freq_hz"] = ((RECORD, "beam", "mode"), np.float64,
                                      {"units": "Hz", "long_name": "mistuned modal frequency"})
    attrs = {
        "title": f"mcfric Monte Carlo ensemble: {model.name}",
        "model_name": model.name,
        "config": spec.config_toml,
        "config_json": spec.config_json,
        "harmonics": np.int64(spec.solver.harmonics),
        "seed": np.int64(spec.seed),
        "samples": np.int64(spec.samples),
        "sampling_contract": "sample i draws from Generator(PCG64(SeedSequence(seed, "
                             "spawn_key=(i,)))); see mcfric.sampling",
        "solver_fingerprint": fingerprint(),
        **software_attrs(),
    }
    placeholders = {"n_not_converged": np.int64(-1), "wall_time_s": np.float64(np.nan),
                    "kernel_time_s": np.float64(np.nan), "bounds_time_s": np.float64(np.nan),
                    "finished_unix": np.float64(np.nan)}
    return coords, variables, attrs, placeholders


def output_bytes(spec):
    """Bytes of the results file of ``spec`` (its records; metadata is small)."""
    coords, variables = layout(spec)[:2]
    n = {d: len(v[0]) for d, v in coords.items()}
    total = spec.samples * 8 + allocated_bytes((spec.samples,), np.int8)   # sample, done
    for dims, dtype, _ in variables.values():
        total += allocated_bytes((spec.samples, *(n[d] for d in dims[1:])), dtype)
    return int(total)


def peak_memory_bytes(spec):
    """A rough upper estimate of a run's peak memory, bytes: three chunks of output (in
    the kernel, in the queue, in the writer), the receptances, each thread's scratch (of
    the dense fallback, or of the multi-harmonic kernel), and the bounds' dense
    contact-space matrices."""
    nb, nd = spec.model.n_beams, spec.model.n_dampers
    n_f = len(spec.freq_hz)
    n_h = (spec.solver.harmonics + 1) // 2
    chunk = chunk_samples(spec)
    est = 3 * chunk * (output_bytes(spec) / spec.samples)
    est += n_f * 4 * nb * 16 * n_h * (chunk if spec.mistuned else 1)
    import numba

    n_threads = spec.execution.threads or numba.config.NUMBA_NUM_THREADS
    est += min(n_threads, chunk) * hbm.scratch_per_thread(nd, spec.solver.harmonics, n_f,
                                                          spec.solver.n_time)
    if spec.bounds:
        est += 3 * 8 * nb * nd
    return int(est)


def bounds_bytes(spec):
    """The bounds group's bytes at most (checked before the bounds are computed)."""
    from .bounds.results import group_bytes

    return group_bytes(len(spec.freq_hz), spec.model.n_dampers)
