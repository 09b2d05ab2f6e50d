"""Run configuration: a preset or a TOML file, command-line overrides, validated once.

A configuration is resolved in three layers, later ones winning:

1. the defaults of a preset (``model.preset``: ``two-beam``, ``eight-beam``, ``disk-24``
   or ``disk-72``; the rig itself comes from :mod:`mcfric.presets`), plus the paper's
   ensemble;
2. the TOML file, key by key (a ``[sampling.<param>]`` distribution table and the
   ``[[model.beam]]`` list are replaced whole, not merged);
3. command-line overrides (``--samples``, ``--F0``, ...).

The result is validated once (:func:`validate`): an unknown key, a wrong type or a value
out of range raises :class:`ConfigError`, whose one-line message names the key (or the
command-line flag that set it) and what is allowed. A valid configuration is complete:
:meth:`Config.toml` renders every key, with comments, and parses back to the same
configuration (``mcfric config PRESET`` prints it); :attr:`Config.spec` is its plain
run specification.

``[run]`` says how to compute (threads, chunk size, checkpoints), never what: it is
excluded from :meth:`Config.identity`, the part that must match for ``--resume``
(as is ``[model] name``, a label).
``[bounds]`` configures the response bounds that ``run`` computes before the ensemble
(and ``mcfric bounds`` alone); it does not change the ensemble and is excluded too.
Every key is described in the docs' configuration reference (``docs/configuration.md``).

Modules: :mod:`.schema` (keys, checks, defaults, comments), :mod:`.validation` (the
whole-configuration checks), :mod:`.loading` (preset, file, overrides, modal files),
:mod:`.rendering` (TOML text), :mod:`.configuration` (:class:`Config` and its run
specification).
"""

from ..validators import InputError as ConfigError
from .configuration import Config, first_difference
from .loading import load, read_toml
from .rendering import render, template
from .schema import DEFAULT_PRESET, NOT_IDENTITY, SPEC, defaults, identity
from .validation import bounds_limits, check_keys, validate

__all__ = ["ConfigError", "Config", "first_difference", "load", "read_toml", "render",
           "template", "DEFAULT_PRESET", "NOT_IDENTITY", "SPEC", "defaults", "identity",
           "bounds_limits", "check_keys", "validate"]
