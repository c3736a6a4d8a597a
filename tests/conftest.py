import os

import pytest

from nrsfm.paths import user_path


@pytest.fixture(scope="session")
def mocap_dir():
    """The MoCap folder from NRSFM_DATA; skipped locally when unset, an error in CI."""
    root = os.environ.get("NRSFM_DATA")
    folder = user_path(root) / "mocap" if root else None
    if folder is None or not folder.is_dir():
        if os.environ.get("CI"):
            pytest.fail("CI must set NRSFM_DATA to a folder holding mocap/")
        pytest.skip("NRSFM_DATA not set (or has no mocap/): benchmark-data tests skipped")
    return folder
