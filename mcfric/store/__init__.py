"""The results file: a chunked HDF5 store that survives being killed at any moment.

The store knows records (rows along one "record" dimension, here the samples), named
dimensions, arrays and groups; it knows nothing of physics. Every HDF5 write of mcfric
goes through it. The layout that :mod:`mcfric.ensemble` writes into it is a public
interface, documented in the docs' results-file page.

Modules: :mod:`.files` (the ``.partial`` suffix, errors, fsync), :mod:`.writer` (the
crash-safe record writer :class:`Store`), :mod:`.groups` (groups of labelled arrays, and
small files of coordinates and groups), :mod:`.reader` (attributes, records in blocks,
groups, xarray).
"""

from .files import LAYOUT_VERSION, StoreError, partial_path, replacing
from .groups import add_group, write_file
from .reader import (
                     dataset_names,
                     describe,
                     iter_records,
                     open_results,
                     read,
                     read_attrs,
                     read_group,
)
from .writer import Store, allocated_bytes

__all__ = ["LAYOUT_VERSION", "StoreError", "partial_path", "replacing", "add_group", "write_file",
           "dataset_names", "describe", "iter_records", "open_results", "read", "read_attrs",
           "read_group", "Store", "allocated_bytes"]
