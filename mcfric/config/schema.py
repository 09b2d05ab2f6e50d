"""The configuration schema: every key, its check, its default and its comment.

One entry per key: ``(check, comment)``. A check takes ``(value, key)`` and returns the
canonical value or raises :class:`~mcfric.validators.InputError`
(:mod:`mcfric.validators`); the comment is what ``mcfric config`` prints beside the key.
Defaults come from a preset (:func:`defaults`); units are SI: Hz, N, N/m, m.
"""

from __future__ import annotations

from .. import sampling
from ..metric import QUANTITIES
from ..model import PATTERNS, TOPOLOGIES
from ..presets import PRESETS
from ..presets import preset as make_preset
from ..validators import (
    F0_RANGE,
    MAX_FREQ_HZ,
    RESIDUAL_TOL_MAX,
    RESIDUAL_TOL_MIN,
    InputError,
    auto_or_boolean,
    auto_or_integer,
    auto_or_number,
    beams_or_all,
    boolean,
    choice,
    choices,
    integer,
    integer_list,
    integers,
    matrix,
    number,
    numbers,
    odd_integer,
    scheduler_address,
    show,
    string,
)

DEFAULT_PRESET = "eight-beam"
SPACINGS = ("linear", "log")
#: Sections that do not change the results (ignored when comparing runs for --resume),
#: nor does the model's ``name``, a label (:func:`identity`).
NOT_IDENTITY = ("run", "bounds")
MAX_SAMPLES = 10 ** 10
#: ``output.response = "auto"`` stores the complex response up to this many beams and the
#: float32 amplitude above (docs: results file, "Storage of large rings").
AUTO_COMPLEX_MAX_BEAMS = 32
MAX_FREQ = 10 ** 7


def identity(data):
    """The part of a configuration (nested dict) that determines the results: all but the
    ``NOT_IDENTITY`` sections and the model's ``name`` (so a file keeps resuming when only
    its label differs, e.g. a default name that a later version words otherwise)."""
    out = {k: v for k, v in data.items() if k not in NOT_IDENTITY}
    if isinstance(out.get("model"), dict):
        out["model"] = {k: v for k, v in out["model"].items() if k != "name"}
    return out


def defaults(preset=DEFAULT_PRESET):
    """The complete default configuration of a preset, as a nested dict."""
    if preset not in PRESETS:
        raise InputError("model.preset", f"expected one of {choices(PRESETS)}, "
                         f"got {show(preset)}")
    m = make_preset(preset)
    t = m.beams[0]
    ex = m.excitation
    return {
        "model": {
            "preset": preset, "name": m.name, "n_beams": m.n_beams,
            "topology": m.topology, "contact": m.contact, "output": m.output,
            "drive": m.drive,
            "table": {"freq_hz": t.freq_hz.tolist(), "zeta": t.zeta.tolist(),
                      "shapes": t.shapes.tolist(), "positions": list(t.positions)},
            "beam": [],
        },
        "excitation": {"pattern": ex.pattern, "F0": ex.F0, "beam": ex.beam,
                       "mode": ex.mode, "engine_order": ex.engine_order,
                       "engine_orders": []},
        "frequency": {"f_min": 10.0, "f_max": 150.0, "n": 1000, "spacing": "linear"},
        "sampling": {"samples": 2000, "seed": 0, "mistuning": 0.0, "mistuning_per": "beam",
                     **{k: sampling.as_dict(d) for k, d in sampling.PAPER.items()}},
        "metric": {"quantity": "displacement", "beams": "all"},
        "peaks": {"enabled": True, "count": t.n_modes, "rtol": 1e-4, "window": 3},
        "solver": {"tol": 1e-10, "max_iter": 50, "harmonics": 1, "n_time": 0},
        "output": {"keep_response": True, "response": "auto", "keep_harmonics": False},
        "run": {"threads": 0, "chunk": 0, "checkpoint_s": 0.0, "scheduler": ""},
        "bounds": {"enabled": True, "k_max": "auto", "k_max_im": "auto", "F_lim": "auto",
                   "n_starts": 3, "certify": True, "certify_budget": "auto",
                   "certify_split": 3200, "certify_moments": "auto"},
    }


TABLE = {
    "freq_hz": (numbers(lo=0, lo_open=True), "natural frequencies, Hz, one per mode"),
    "zeta": (numbers(lo=0, hi=1), "modal damping ratios (-), one per mode"),
    "shapes": (matrix(), "mass-normalised mode shapes, kg^-1/2: one row per mode, "
                         "one column per position"),
    "positions": (integers(), "position label of each column of shapes"),
}
BEAM = {
    "beam": (integer(1), "which beam (1-based) this entry overrides"),
    "freq_hz": TABLE["freq_hz"],
    "zeta": TABLE["zeta"],
    "shapes": TABLE["shapes"],
}
DIST_DOC = {
    "mu0": "friction coefficient (-), per damper",
    "kc": "tangential contact stiffness, N/m, per damper",
    "N0": "normal preload, N, per damper",
}

SPEC = {
    "model": {
        "preset": (choice(*PRESETS), "base rig; every other key overrides it"),
        "name": (string(nonblank=True), "free text, shown in plots and in `mcfric info`"),
        "n_beams": (integer(2, 8000), "number of beams (2..8000: a results file keeps the "
                                      "beams of every damper in 64 kB)"),
        "topology": (choice(*TOPOLOGIES), '"linear": n_beams - 1 dampers between '
                                          'neighbours; "circular": also last-first'),
        "contact": (integer(), "position label of the friction contacts"),
        "output": (integer(), "position label of the response output"),
        "drive": (integer(), "position label of the drive force"),
        "table": TABLE,
        "beam": BEAM,
    },
    "excitation": {
        "pattern": (choice(*PATTERNS), '"single": one beam; "mode": F0 cos(m pi (b - 1/2) / n); '
                                       '"travelling": F0 exp(-2 pi i E (b - 1) / n)'),
        "F0": (number(*F0_RANGE), "force amplitude, N (1e-12 to 1e6)"),
        "beam": (integer(1), 'driven beam for "single" (1-based)'),
        "mode": (integer(0), 'chain mode m for "mode"'),
        "engine_order": (integer(), 'engine order E for "travelling"'),
        "engine_orders": (integer_list(), '"travelling", mcfric run only: one run and '
                                          'results file per engine order in the list '
                                          '(FILE-eoE.h5); [] runs engine_order alone'),
    },
    "frequency": {
        "f_min": (number(lo=0, lo_open=True, hi=MAX_FREQ_HZ), "lowest frequency, Hz"),
        "f_max": (number(lo=0, lo_open=True, hi=MAX_FREQ_HZ),
                  "highest frequency, Hz (> f_min)"),
        "n": (integer(2, MAX_FREQ), "number of frequencies (each sample sweeps them upward)"),
        "spacing": (choice(*SPACINGS), '"linear" or "log" spacing'),
    },
    "sampling": {
        "samples": (integer(1, MAX_SAMPLES), "ensemble size"),
        "seed": (integer(0, 2 ** 63 - 1), "root seed; sample i uses SeedSequence(seed, "
                                          "spawn_key=(i,))"),
        "mistuning": (number(lo=0, hi=sampling.MISTUNING_MAX),
                      "relative std of the modal frequencies (0 = none, max 0.1)"),
        "mistuning_per": (choice(*sampling.MISTUNING_PER),
                          '"beam": one factor per beam for all its modes; "mode": '
                          'one per beam and mode'),
        "mu0": "dist",
        "kc": "dist",
        "N0": "dist",
    },
    "metric": {
        "quantity": (choice(*QUANTITIES), "M = max over beams of omega^k |y| at the output "
                                          "position (k = 0, 1, 2)"),
        "beams": (beams_or_all(), '"all" or a list of beam numbers (1-based) to take the '
                                  'maximum over'),
    },
    "peaks": {
        "enabled": (boolean(), "refine every member's largest peaks in frequency and check "
                               "them for folds (stored in peak_*)"),
        "count": (integer(1, 100), "peaks kept per member, largest first (default: one "
                                   "per mode of the table)"),
        "rtol": (number(lo=0, hi=0.1, lo_open=True), "relative tolerance of a refined "
                                                     "peak's amplitude"),
        "window": (integer(1, 1000), "grid points on each side of a peak swept downward "
                                     "to look for folds"),
    },
    "solver": {
        "tol": (number(lo=RESIDUAL_TOL_MIN, hi=RESIDUAL_TOL_MAX),
                "accepted relative friction-force residual"),
        "max_iter": (integer(1, 10000), "Newton iterations per attempt (multi-harmonic: "
                                         "plus up to 10 undamped steps where it crawls)"),
        "harmonics": (odd_integer(1, 99), "highest odd harmonic balanced (1: the "
                                          "single-harmonic describing function; 3, 5, ...: "
                                          "multi-harmonic balance of the odd harmonics)"),
        "n_time": (integer(0, 65536), "AFT samples per period bracketing the stick-slip "
                                      "events (0 = auto, max(32, 8 H)); at least 4 H + 4"),
    },
    "output": {
        "keep_response": (boolean(), "store the complex response per beam; false keeps only "
                                     "the metric (for very large runs)"),
        "response": (choice("auto", "complex", "amplitude"),
                     'how the response per beam is stored: "complex" (complex128, 16 bytes a '
                     'point), "amplitude" (|X| in float32, 4 bytes); "auto": complex up to '
                     f'{AUTO_COMPLEX_MAX_BEAMS} beams, amplitude above'),
        "keep_harmonics": (boolean(), "with harmonics > 1: also store every odd harmonic "
                                      "of the response (response_harmonics)"),
    },
    "run": {
        "threads": (integer(0), "numba threads (0 = all); never changes the results"),
        "chunk": (integer(0, 10 ** 7), "samples per chunk (0 = auto, ~32 MB of kernel output); "
                                       "never changes the results"),
        "checkpoint_s": (number(lo=0), "min seconds between crash-safe checkpoints "
                                       "(0 = after every chunk)"),
        "scheduler": (scheduler_address(), 'run the chunks on Dask: "local:N" (N worker '
                                           'processes here) or "tcp://host:port" ("" = in '
                                           'this process); never changes the results'),
    },
    "bounds": {
        "enabled": (boolean(), "compute the equivalent-linear response bounds "
                               "before the ensemble, stored in bounds/"),
        "k_max": (auto_or_number(), 'largest stiffness Re K of a damper, N/m; "auto": the '
                                    'upper limit of the kc distribution'),
        "k_max_im": (auto_or_number(), 'largest dissipation Im K, N/m; "auto": k_max'),
        "F_lim": (auto_or_number(words=("auto", "none")),
                  'friction force limit (first harmonic), N; "auto": 4/pi mu0_max N0_max '
                  'from the sampling; "none": no force constraint'),
        "n_starts": (integer(1, 10000), "starts of the box search per frequency"),
        "certify": (boolean(), "also certify the bounds over the admissible set by branch "
                               "and bound (bounds/upper_certified, lower_certified); false "
                               "for a quick look"),
        "certify_budget": (auto_or_integer(1, 1000000), "enclosures per frequency and bound "
                           'of the certification at most; "auto": 4000 for one damper, 400 '
                           "for more (50 from six dampers with a force limit)"),
        "certify_split": (integer(0, 1000000), "relaxations of parts of the box per "
                          "frequency where the relaxation of the whole box leaves the upper "
                          "bound loose (branch and bound over relaxations; the beams after "
                          "the first share a quarter more; the lower bound at most 800; "
                          "0: none)"),
        "certify_moments": (auto_or_boolean(), "tighten the certified upper bound by a "
                            "second-order moment relaxation where the first order leaves "
                            'it loose; "auto": where it applies (chains of 2-7 dampers '
                            "with a force limit), false: the first order alone (about a "
                            "third of the time; looser near some resonances), true: an "
                            "error where it cannot run"),
    },
}
SECTION_DOC = {
    "model": "the beam array (docs: theory, The rig)",
    "model.table": "modal table of every beam (default paper Table 1; a table given as "
                   "file = ... is read once and stored here as numbers)",
    "model.beam": "per-beam overrides of the table (mistuned or measured beams)",
    "excitation": "harmonic drive at the drive position (docs: theory, Excitation)",
    "frequency": "the frequency grid",
    "sampling": "the Monte Carlo ensemble (docs: theory, Monte Carlo ensembles)",
    "metric": "response metric M per sample and frequency (docs: theory, Response metric)",
    "peaks": "resolved peaks and fold checks of every member (docs: peaks)",
    "solver": "harmonic-balance solver",
    "output": "what the results file keeps",
    "run": "how to compute: never changes the results, not compared on --resume",
    "bounds": "equivalent-linear response bounds (docs: bounds); do not change the ensemble",
}
