"""Figures (matplotlib, Agg canvas: no display and no pyplot state needed).

Small placeholders until the plotting stage (issue 5) replaces them: :func:`ensemble_figure`
(the ensemble cloud written next to a results file by ``mcfric run``) and
:func:`hbm_figure` (``mcfric hbm``). ``mcfric run`` calls ``ensemble_figure`` only if this
module defines it.
"""

from __future__ import annotations

import numpy as np

from .store import iter_records, read, read_attrs


def _figure(size=(8, 4.5)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def ensemble_figure(results_path, png_path, max_lines=400):
    """Grey cloud of the ensemble metric (log amplitude vs frequency) with its envelope.

    Reads the file in blocks: memory does not grow with the number of samples. At most
    ``max_lines`` sample curves are drawn (evenly spread over the ensemble); the envelope
    (min and max over every stored sample) is exact. Non-converged points (NaN) are gaps.

    Parameters
    ----------
    results_path : str or Path
        A results file of ``mcfric run``.
    png_path : str or Path
        Where to write the PNG.
    """
    attrs = read_attrs(results_path)
    f = read(results_path, "frequency")
    n = int(attrs.get("samples", 1))
    step = max(1, n // max_lines)
    lo = np.full(len(f), np.inf)
    hi = np.full(len(f), -np.inf)
    lines = []
    for start, arrays in iter_records(results_path, ["metric", "sample"]):
        m = arrays["metric"]
        lo = np.fmin(lo, np.where(np.isnan(m), np.inf, m).min(axis=0))
        hi = np.fmax(hi, np.where(np.isnan(m), -np.inf, m).max(axis=0))
        pick = arrays["sample"] % step == 0
        lines.extend(m[pick])
    fig = _figure()
    ax = fig.add_subplot()
    if lines:
        y = np.array(lines).T
        ax.plot(f, np.where(y > 0, y, np.nan), color="0.5", lw=0.4, alpha=0.35)
    env = np.isfinite(lo) & np.isfinite(hi)
    ax.plot(f[env], hi[env], color="k", lw=1.2, label="ensemble max")
    ax.plot(f[env], np.where(lo[env] > 0, lo[env], np.nan), color="k", lw=1.2, ls="--",
            label="ensemble min")
    ax.set_yscale("log")
    ax.set_xlabel("frequency [Hz]")
    q = attrs.get("config_json", "")
    unit = "m/s^2" if '"acceleration"' in q else "m/s" if '"velocity"' in q else "m"
    ax.set_ylabel(f"response metric M [{unit}]")
    ax.set_title(f"{attrs.get('model_name', '')}: {n} samples "
                 f"({len(lines)} drawn), seed {attrs.get('seed')}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    fig.savefig(png_path, dpi=120)
    return png_path


def hbm_figure(freq_hz, amplitude, metric, converged, png_path, title="",
               metric_label="M [m]"):
    """Log amplitude vs frequency of one parameter set: each beam a line, the metric bold.

    Parameters
    ----------
    freq_hz : ndarray, shape (n_f,)
    amplitude : ndarray, shape (n_f, n_beams)
        ``|y|`` per beam, m.
    metric : ndarray, shape (n_f,)
    converged : ndarray of bool, shape (n_f,)
        Non-converged points are not drawn.
    png_path : str or Path
    """
    ok = np.asarray(converged, bool)
    amp = np.where(ok[:, None], amplitude, np.nan)
    met = np.where(ok, metric, np.nan)
    fig = _figure()
    ax = fig.add_subplot()
    for b in range(amp.shape[1]):
        ax.plot(freq_hz, np.where(amp[:, b] > 0, amp[:, b], np.nan), lw=0.9,
                label=f"beam {b + 1}")
    ax.plot(freq_hz, np.where(met > 0, met, np.nan), color="k", lw=2.4, label=metric_label)
    ax.set_yscale("log")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("amplitude at the output position")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2 if amp.shape[1] > 4 else 1)
    fig.savefig(png_path, dpi=120)
    return png_path
