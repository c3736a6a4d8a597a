"""Published figures the project compares against (``nrsfm/data/published.json``).

The file holds numbers only (the paper's tables, the baselines it quotes, and a peer's
measurements of Dai et al.'s code), each section with its source under ``"sources"``.
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

__all__ = ["published", "published_value"]


@lru_cache(maxsize=1)
def _load():
    text = resources.files("nrsfm").joinpath("data/published.json").read_text()
    return json.loads(text)


def published():
    """The whole table as a dict (a fresh copy): section -> column -> sequence -> value."""
    return json.loads(json.dumps(_load()))


def published_value(section, column, name=None):
    """One published figure, or None when the source gives none.

    Parameters
    ----------
    section : str
        e.g. ``"mocap_e3d"``, ``"mocap_rotation_error"``, ``"peer_bmm_octave"``.
    column : str
        e.g. ``"ours"``, ``"BMM"``, ``"e3d_akhter"``.
    name : str, optional
        Sequence name; without it the whole column (dict) is returned.
    """
    col = _load().get(section, {}).get(column)
    if col is None or name is None:
        return col
    return col.get(name)
