import os
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def mocap_dir():
    """The MoCap folder from NRSFM_DATA; skipped locally when unset, an error in CI."""
    root = os.environ.get("NRSFM_DATA")
    if not root or not (Path(root) / "mocap").is_dir():
        if os.environ.get("CI"):
            pytest.fail("CI must set NRSFM_DATA to a folder holding mocap/ (../shared/data)")
        pytest.skip("NRSFM_DATA not set: benchmark-data tests skipped")
    return Path(root) / "mocap"
