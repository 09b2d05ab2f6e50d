"""mcfric: response of friction-damped beam arrays under uncertain friction.

Harmonic-balance (describing-function) responses, Monte Carlo ensembles and
equivalent-linear response bounds, after "Predicting response bounds for friction-damped
gas turbine blades with uncertain friction coupling".
"""

from .hbm import HBMResult, solve
from .model import TABLE_1, Excitation, ModalTable, Model
from .presets import disk, eight_beam, preset, two_beam
from .provenance import __version__
from .store import open_results

__all__ = ["HBMResult", "solve", "TABLE_1", "Excitation", "ModalTable", "Model",
           "disk", "eight_beam", "preset", "two_beam", "open_results", "__version__"]
