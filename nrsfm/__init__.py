"""nrsfm: non-rigid structure from motion by matrix factorisation with organic priors.

Kumar & Van Gool, "Organic Priors in Non-Rigid Structure from Motion", ECCV 2022.
"""

from .diagnostics import NRSfMWarning
from .metrics import e3d, e3d_akhter, rotation_error
from .pipeline import METHODS, Reconstruction, reconstruct

__version__ = "0.1.0"

__all__ = ["METHODS", "NRSfMWarning", "Reconstruction", "reconstruct", "e3d", "e3d_akhter",
           "rotation_error", "__version__"]
