"""Equivalent-linear response bounds: valid for every friction law in an admissible region.

Modules: :mod:`.equivalent_linear` (the admissible region, :func:`compute_bounds` and
:class:`Bounds`), :mod:`.search` (the box search over frequencies, on threads),
:mod:`.results` (the ``bounds/`` group of results files and bounds-only files),
:mod:`.members_check` (an ensemble's members against the bounds in its file).
"""

from .equivalent_linear import (
                                LIMITED_BY,
                                MAX_SWEEPS,
                                N_STARTS,
                                Bounds,
                                compute_bounds,
                                force_limit,
                                from_spec,
                                rotation_invariant,
)
from .members_check import MembersCheck, check_members
from .results import read_bounds, to_group, write_bounds_file

__all__ = ["LIMITED_BY", "MAX_SWEEPS", "N_STARTS", "Bounds", "MembersCheck", "check_members",
           "compute_bounds", "force_limit", "from_spec", "read_bounds", "rotation_invariant",
           "to_group", "write_bounds_file"]
