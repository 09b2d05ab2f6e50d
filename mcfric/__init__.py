"""mcfric: response of friction-damped beam arrays under uncertain friction.

Harmonic-balance (describing-function) responses, Monte Carlo ensembles and
equivalent-linear response bounds, after "Predicting response bounds for friction-damped
gas turbine blades with uncertain friction coupling".
"""

#: The public names and their modules, loaded on first use: the command line's entry
#: point (:func:`mcfric.cli.main`) starts before numpy and numba load, so that Ctrl-C
#: while they load is one line, not a traceback.
_PUBLIC = {"HBMResult": "hbm", "solve": "hbm", "TABLE_1": "model", "Excitation": "model",
           "ModalTable": "model", "Model": "model", "disk": "presets",
           "eight_beam": "presets", "preset": "presets", "two_beam": "presets",
           "open_results": "store", "__version__": "provenance"}

__all__ = ["HBMResult", "solve", "TABLE_1", "Excitation", "ModalTable", "Model",
           "disk", "eight_beam", "preset", "two_beam", "open_results", "__version__"]


def __getattr__(name):
    from importlib import import_module

    module = _PUBLIC.get(name)
    if module is None:
        # a submodule (``mcfric.ensemble.run`` after ``import mcfric``), as before
        try:
            return import_module(f".{name}", __name__)
        except ModuleNotFoundError as e:
            if e.name != f"{__name__}.{name}":
                raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value          # once: later lookups find it directly
    return value


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC))
