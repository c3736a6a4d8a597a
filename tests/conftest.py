import os

import pytest

from nrsfm.paths import mocap_dir as find_mocap_dir


@pytest.fixture(scope="session")
def mocap_dir():
    """The MoCap folder from NRSFM_DATA (the folder that holds mocap/, or mocap/ itself);
    skipped locally when unset, an error in CI."""
    root = os.environ.get("NRSFM_DATA")
    folder = find_mocap_dir(root) if root else None
    if folder is None or not (folder / "pickup.mat").is_file():
        if os.environ.get("CI"):
            pytest.fail("CI must set NRSFM_DATA to the folder that holds mocap/ (or mocap/ itself)")
        pytest.skip("NRSFM_DATA not set (or has no mocap/): benchmark-data tests skipped")
    return folder
