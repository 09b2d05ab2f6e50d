"""The validated configuration, and its resolution into a plain run specification.

A :class:`Config` is what :func:`~mcfric.config.load` and
:func:`~mcfric.config.validate` return: a complete nested dict of canonical values. Its
:attr:`Config.spec` resolves it, once, into a :class:`~mcfric.spec.RunSpec` (the model,
the sampler, the frequency grid, the solver and bounds settings, the output layout) that
the ensemble, the bounds and the command line use without coming back here.
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .. import sampling
from ..model import Excitation, ModalTable, Model
from ..peaks import PeakSettings
from ..spec import BoundsSpec, ExecutionSpec, MetricSpec, RunSpec, SolverSpec
from ..validators import InputError
from . import loading, rendering, validation  # used at call time (they import Config)
from .schema import AUTO_COMPLEX_MAX_BEAMS, defaults, identity


@dataclass(frozen=True)
class Config:
    """A validated, complete configuration (``data``: nested dict of canonical values)."""

    data: dict

    def __getitem__(self, section):
        return self.data[section]

    @cached_property
    def spec(self):
        """The :class:`~mcfric.spec.RunSpec` of this configuration (resolved once)."""
        d = self.data
        model = _model(d)
        s = d["sampling"]
        dists = {k: sampling.distribution(s[k]["dist"],
                                          **{p: v for p, v in s[k].items() if p != "dist"})
                 for k in ("mu0", "kc", "N0")}
        sampler = sampling.Sampler(seed=s["seed"], n_dampers=model.n_dampers,
                                   modal_freq_hz=model.modal_arrays()[0],
                                   mistuning=s["mistuning"], mistuning_per=s["mistuning_per"],
                                   **dists)
        f = d["frequency"]
        space = np.linspace if f["spacing"] == "linear" else np.geomspace
        freq = space(f["f_min"], f["f_max"], f["n"])
        freq.setflags(write=False)
        beams = d["metric"]["beams"]
        b = d["bounds"]
        if b["enabled"] and not np.all(model.modal_arrays()[1] > 0):
            raise InputError("model.table.zeta", "the bounds need every mode damped (zeta > 0):"
                             " an undamped mode has an unbounded resonance; give zeta > 0 or "
                             "set bounds.enabled = false")
        limits = validation.bounds_limits(d) if b["enabled"] else None
        if b["enabled"]:
            from ..bounds.equivalent_linear import check_scales
            check_scales(model, limits[0], limits[1], key="model.table")
        moments = b["certify_moments"]
        if b["enabled"] and b["certify"]:
            from ..bounds.certified import resolve_moments
            try:
                moments = resolve_moments(moments, model.topology == "linear",
                                          model.n_dampers, limits[2])
            except ValueError as e:
                raise InputError("bounds.certify_moments", str(e).split(": ", 1)[1]) from None
        bounds = (BoundsSpec(*limits, n_starts=b["n_starts"],
                             certify=b["certify"],
                             budget=None if b["certify_budget"] == "auto" else b["certify_budget"],
                             split=b["certify_split"], moments=moments)
                  if b["enabled"] else None)
        r = d["run"]
        metric = MetricSpec(d["metric"]["quantity"],
                            None if beams == "all" else tuple(x - 1 for x in beams))
        pk = d["peaks"]
        sv = d["solver"]
        # peak refinement and fold detection are single-harmonic (docs: running)
        peaks = (PeakSettings(count=pk["count"], rtol=pk["rtol"], window=pk["window"],
                              quantity=metric.quantity, beams=metric.beams)
                 if pk["enabled"] and sv["harmonics"] == 1 else None)
        return RunSpec(
            model=model, freq_hz=freq, sampler=sampler, samples=s["samples"],
            metric=metric,
            solver=SolverSpec(sv["tol"], sv["max_iter"], sv["harmonics"], sv["n_time"] or None),
            peaks=peaks, keep_harmonics=d["output"]["keep_harmonics"],
            bounds=bounds, keep_response=d["output"]["keep_response"],
            response_format=response_format(d["output"]["response"], model.n_beams),
            execution=ExecutionSpec(r["threads"] or None, r["chunk"], r["checkpoint_s"],
                                    r["scheduler"]),
            config_toml=self.toml(comments=False), config_json=self.json(),
            identity=self.identity())

    def model(self):
        """The :class:`~mcfric.model.Model` described by ``[model]`` and ``[excitation]``."""
        return self.spec.model

    def frequencies(self):
        """The frequency grid, Hz, shape (n,), increasing (read-only)."""
        return self.spec.freq_hz

    def sampler(self):
        """The :class:`~mcfric.sampling.Sampler` of ``[sampling]``."""
        return self.spec.sampler

    def bounds_limits(self):
        """(k_max_re, k_max_im, F_lim): the admissible region of the bounds, N/m, N/m, N
        (``F_lim`` inf: no force constraint)."""
        return validation.bounds_limits(self.data)

    def bounds_shortfalls(self):
        """Phrases naming the ``[bounds]`` constraints that leave out friction the
        sampling draws (empty: every member is admitted)."""
        return validation.bounds_shortfalls(self.data)

    def idle_settings(self, sections=None):
        """Phrases naming the settings changed from the preset's defaults that do nothing
        here, of the tables ``sections`` or all
        (:func:`~mcfric.config.validation.idle_settings`)."""
        return validation.idle_settings(self.data, sections)

    def metric_beams(self):
        """0-based beams of the metric, or None for all."""
        b = self.spec.metric.beams
        return None if b is None else list(b)

    @property
    def samples(self):
        """Ensemble size (``sampling.samples``)."""
        return self.data["sampling"]["samples"]

    @property
    def seed(self):
        """Root seed (``sampling.seed``)."""
        return self.data["sampling"]["seed"]

    def identity(self):
        """The part of the configuration that determines the results (no [run], [bounds],
        nor the model's name)."""
        return identity(self.data)

    def json(self, identity=False):
        """Canonical JSON (sorted keys; floats round-trip exactly)."""
        return json.dumps(self.identity() if identity else self.data, sort_keys=True)

    def toml(self, comments=True):
        """The complete configuration as TOML (parses back to the same configuration)."""
        return rendering.render(self.data, comments)

    def replace(self, dotted, value):
        """A validated copy with one key changed.

        Parameters
        ----------
        dotted : str
            The key, e.g. ``"sampling.samples"`` (docs: configuration); a new
            ``"model.n_beams"`` renames a preset that carries its automatic name (as
            :func:`~mcfric.config.load` names it).
        value
            Its new value in the configuration's units (Hz, N, N/m, m), as a TOML file
            gives it (numpy values are taken as Python's).

        Returns
        -------
        Config

        Raises
        ------
        InputError
            The value (or the configuration it makes) is not valid.
        """
        raw = copy.deepcopy(self.data)
        loading.set_key(raw, dotted, _plain(value))
        if dotted == "model.n_beams":
            m = self.data["model"]
            n_preset = defaults(m["preset"])["model"]["n_beams"]
            if m["name"] == loading.automatic_name(m["preset"], m["n_beams"], n_preset):
                raw["model"]["name"] = loading.automatic_name(m["preset"], value, n_preset)
        return validation.validate(raw)


def _plain(value):
    """``value`` with numpy arrays and scalars (also inside lists) as Python's own, as a
    TOML file gives them."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def response_format(setting, n_beams):
    """``output.response`` resolved: ``"complex"`` or ``"amplitude"`` (``"auto"`` by size)."""
    if setting != "auto":
        return setting
    return "complex" if n_beams <= AUTO_COMPLEX_MAX_BEAMS else "amplitude"


def _model(d):
    """The :class:`~mcfric.model.Model` of ``[model]`` and ``[excitation]``."""
    m, t = d["model"], d["model"]["table"]
    table = ModalTable(t["freq_hz"], t["zeta"], t["shapes"], tuple(t["positions"]))
    beams = [table] * m["n_beams"]
    for b in m["beam"]:
        beams[b["beam"] - 1] = ModalTable(b.get("freq_hz", t["freq_hz"]),
                                          b.get("zeta", t["zeta"]),
                                          b.get("shapes", t["shapes"]),
                                          tuple(t["positions"]))
    # engine_orders is a sweep of runs (mcfric run), each with its own engine_order: the
    # sweep's model is its first run's (the preset's engine_order may not fit its beams)
    ex = {k: v for k, v in d["excitation"].items() if k != "engine_orders"}
    if d["excitation"]["engine_orders"]:
        ex["engine_order"] = d["excitation"]["engine_orders"][0]
    return Model(beams=tuple(beams), excitation=Excitation(**ex),
                 topology=m["topology"], contact=m["contact"], output=m["output"],
                 drive=m["drive"], name=m["name"])


def first_difference(a, b, path=""):
    """Dotted key of the first difference between two nested dicts, or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            d = first_difference(a.get(k), b.get(k), f"{path}.{k}" if path else k)
            if d:
                return d
        return None
    return None if a == b else path
