"""Published figures the project compares against (``nrsfm/data/published.json``): the
paper's tables, the baselines it quotes and a peer's measurements of Dai et al.'s code, each
section with its source under ``"sources"``."""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources


@lru_cache(maxsize=1)
def _load():
    return json.loads(resources.files("nrsfm").joinpath("data/published.json").read_text())


def published_value(section, column, name=None):
    """One published figure (``section`` e.g. ``"mocap_e3d"``, ``column`` e.g. ``"ours"``,
    ``name`` a sequence), None when the source gives none; without ``name`` the column."""
    col = _load().get(section, {}).get(column)
    return col if col is None or name is None else col.get(name)
