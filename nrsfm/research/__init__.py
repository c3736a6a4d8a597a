"""Research variants, apart from the core: the rotation strategies and step variants the
measurements in ``docs/rotation_stage.md`` compared the production stage with, and their
settings (:mod:`.rotations`), the family combination (:mod:`.family`), and the triplet
starts other than the search (:mod:`.triplets`). The production path
(:func:`nrsfm.reconstruct` with its presets) never imports this package; a run with a
research strategy takes ``reconstruct(W, K, settings=research_settings("literal"))``.
"""

from .rotations import RotationAblationSettings, research_settings, rotation_settings

__all__ = ["RotationAblationSettings", "research_settings", "rotation_settings"]
