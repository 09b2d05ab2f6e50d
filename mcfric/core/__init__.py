"""Pure numba kernels on float64/complex128 arrays in SI units.

Nothing in this sub-package imports the rest of mcfric: it knows no configs, files or
progress bars. Kernels never raise and never allocate their outputs; they report
status codes.
"""
