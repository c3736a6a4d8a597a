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
            pytest.fail("CI must set NRSFM_DATA to the folder that holds mocap/ "
                        "(or mocap/ itself)")
        pytest.skip("NRSFM_DATA not set (or has no mocap/): benchmark-data tests skipped")
    return folder


# Warnings these tests trigger today, each allowed for its test only and still printed
# (not errors: they are owned by work in progress on the completion and settings, issue 21);
# remove an entry once its test asserts the warning (pytest.warns) or no longer triggers it.
# Every other warning fails the suite (pyproject.toml, filterwarnings = ["error"]).
_CAP = "default:the completion of W stopped at its iteration cap:RuntimeWarning"
_DEPTH_SIGN = ("default:unreliable reconstruction. [^;]* had their depth sign set by motion "
               "smoothness[^;]*$:nrsfm.diagnostics.NRSfMWarning")     # ("." for ":")
_PENDING_WARNINGS = {
    "tests/test_completion.py::test_reconstruct_with_missing_data": _CAP,
    "tests/test_completion_fast.py::test_lags_rule_and_completion_setting_through_reconstruct":
        _CAP,
    "tests/test_completion_fast.py::test_auto_completion_follows_the_lags_rule": _CAP,
    "tests/test_settings.py::test_rotation_strategy_through_reconstruct": _DEPTH_SIGN,
    "tests/test_settings.py::test_typed_settings_equal_the_dict_form": _DEPTH_SIGN,
}


def pytest_collection_modifyitems(items):
    for item in items:
        rule = _PENDING_WARNINGS.get(item.nodeid)
        if rule:
            item.add_marker(pytest.mark.filterwarnings(rule))
