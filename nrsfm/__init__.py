"""nrsfm: non-rigid structure from motion by matrix factorisation with organic priors.

Kumar & Van Gool, "Organic Priors in Non-Rigid Structure from Motion", ECCV 2022.
Layers and data flow: ``docs/architecture.md``.
"""

from .diagnostics import NRSfMWarning
from .metrics import e3d, e3d_akhter, rotation_error
from .pipeline import Reconstruction, reconstruct
from .settings import METHODS, AdmmSettings, BilinearSettings, MeasurementSettings
from .settings import PerspectiveSettings, RotationSettings, Settings

__version__ = "0.1.0"

__all__ = [
    "METHODS",
    "AdmmSettings",
    "BilinearSettings",
    "MeasurementSettings",
    "NRSfMWarning",
    "PerspectiveSettings",
    "Reconstruction",
    "RotationSettings",
    "Settings",
    "e3d",
    "e3d_akhter",
    "reconstruct",
    "rotation_error",
    "__version__",
]
