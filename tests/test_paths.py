"""nrsfm.paths: the user's folder, outputs outside the package, the data folder."""

from pathlib import Path

import numpy as np
import pytest
import scipy.io

import data_tools as dt
import nrsfm
from nrsfm import paths


def test_user_folder_prefers_pwd(monkeypatch, tmp_path):
    start = tmp_path / "start"
    start.mkdir()
    kernel = tmp_path / "kernel"
    kernel.mkdir()
    monkeypatch.chdir(kernel)
    monkeypatch.setenv("PWD", str(start))
    assert paths.user_folder() == start


@pytest.mark.parametrize("pwd", [None, "", "relative/dir", "/no/such/folder/for/nrsfm"])
def test_user_folder_falls_back_to_cwd(monkeypatch, tmp_path, pwd):
    monkeypatch.chdir(tmp_path)
    if pwd is None:
        monkeypatch.delenv("PWD", raising=False)
    else:
        monkeypatch.setenv("PWD", pwd)
    assert paths.user_folder() == Path.cwd()


def test_user_path(monkeypatch, tmp_path):
    monkeypatch.chdir("/")
    monkeypatch.setenv("PWD", str(tmp_path))
    assert paths.user_path("a/b.npz") == tmp_path / "a" / "b.npz"
    assert paths.user_path(tmp_path / "x") == tmp_path / "x"
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert paths.user_path("~/y") == tmp_path / "home" / "y"


def test_output_dir_default_and_env(monkeypatch, tmp_path):
    monkeypatch.setenv("PWD", str(tmp_path))
    monkeypatch.delenv("NRSFM_OUT", raising=False)
    d = paths.output_dir("notebooks", "x")
    assert d == tmp_path / "out" / "notebooks" / "x" and d.is_dir()
    monkeypatch.setenv("NRSFM_OUT", "results")
    d = paths.output_dir("notebooks")
    assert d == tmp_path / "results" / "notebooks" and d.is_dir()
    monkeypatch.setenv("NRSFM_OUT", str(tmp_path / "abs"))
    assert paths.output_dir() == tmp_path / "abs"


def test_output_dir_never_inside_the_package(monkeypatch):
    pkg = Path(nrsfm.__file__).resolve().parent
    monkeypatch.setenv("PWD", str(pkg))
    monkeypatch.delenv("NRSFM_OUT", raising=False)
    with pytest.raises(ValueError, match="inside the installed nrsfm package"):
        paths.output_dir("notebooks")
    assert not (pkg / "out").exists()


def test_data_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("PWD", str(tmp_path))
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    with pytest.raises(FileNotFoundError, match="NRSFM_DATA") as info:
        paths.data_dir()
    assert "\n" not in str(info.value)
    assert paths.data_dir("d") == tmp_path / "d"
    monkeypatch.setenv("NRSFM_DATA", "rel/data")
    assert paths.data_dir() == tmp_path / "rel" / "data"
    assert paths.data_dir(tmp_path / "explicit") == tmp_path / "explicit"


def test_relative_nrsfm_data_resolves_against_the_users_folder(monkeypatch, tmp_path):
    """A data folder holding only mocap/ (relative NRSFM_DATA, kernel in another folder)."""
    data = tmp_path / "copy" / "mocap"
    data.mkdir(parents=True)
    rng = np.random.default_rng(0)
    F, P = 4, 5
    P3 = rng.standard_normal((3 * F, P))
    scipy.io.savemat(data / "shark.mat", {"P3_gt": P3})
    kernel = tmp_path / "notebooks"
    kernel.mkdir()
    monkeypatch.chdir(kernel)
    monkeypatch.setenv("PWD", str(tmp_path))
    monkeypatch.setenv("NRSFM_DATA", "copy")
    seq = dt.load_mocap("shark")
    assert seq.shapes.shape == (F, 3, P)
    assert dt.mocap_dir() == data


def _shark_folder(root):
    """``root/mocap/shark.mat``, a tiny Torresani-layout file; returns the mocap folder."""
    folder = root / "mocap"
    folder.mkdir(parents=True)
    P3 = np.random.default_rng(2).standard_normal((3 * 4, 5))
    scipy.io.savemat(folder / "shark.mat", {"P3_gt": P3})
    return folder


@pytest.mark.parametrize("form", ["parent", "mocap"])
def test_data_folder_is_the_parent_of_mocap_or_mocap_itself(monkeypatch, tmp_path, form):
    """``data_dir=`` and ``NRSFM_DATA`` take the same folder, in both forms."""
    folder = _shark_folder(tmp_path / "data")
    given = folder.parent if form == "parent" else folder
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    assert dt.load_mocap("shark", given).shapes.shape == (4, 3, 5)
    assert dt.mocap_dir(given) == folder and paths.mocap_dir(given) == folder
    monkeypatch.setenv("NRSFM_DATA", str(given))
    assert dt.load_mocap("shark").shapes.shape == (4, 3, 5)
    assert dt.mocap_dir() == folder


def test_missing_mocap_file_names_the_folders_searched(monkeypatch, tmp_path):
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    folder = _shark_folder(tmp_path / "data")
    with pytest.raises(FileNotFoundError) as info:
        dt.load_mocap("drink", folder.parent)
    msg = str(info.value)
    assert f"looked in {folder} and {folder.parent};" in msg
    assert "the folder that holds mocap/ (or mocap/ itself)" in msg and "NRSFM_DATA" in msg
    with pytest.raises(FileNotFoundError, match=f"looked in {folder};"):
        dt.load_mocap("drink", folder)  # mocap/ itself: not mocap/mocap
    with pytest.raises(FileNotFoundError, match="no such folder.*no such folder"):
        dt.load_mocap("drink", tmp_path / "nowhere")


def test_missing_mocap_file_points_at_the_folder_one_level_down(tmp_path):
    """Given the grandparent of mocap/ (the folder above the data folder), name the folder
    to use."""
    _shark_folder(tmp_path / "data")
    with pytest.raises(FileNotFoundError) as info:
        dt.load_mocap("shark", tmp_path)
    assert str(info.value).endswith(f"{tmp_path / 'data'} holds it: use that folder")


def test_external_data_folder_forms(monkeypatch, tmp_path):
    """The external sequences: the folder that holds external/ or external/ itself, and
    ``$NRSFM_DATA`` when ``$NRSFM_EXTERNAL_DATA`` is not set."""
    ext = tmp_path / "data" / "external" / "back"
    ext.mkdir(parents=True)
    T = np.random.default_rng(3).standard_normal((3, 6, 4))
    scipy.io.savemat(ext / "back_L_3D.mat", {"track3D": T})
    monkeypatch.delenv("NRSFM_EXTERNAL_DATA", raising=False)
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    for given in (tmp_path / "data", tmp_path / "data" / "external"):
        assert dt.load_external("back", given).W.shape == (8, 6)
    monkeypatch.setenv("NRSFM_DATA", str(tmp_path / "data"))
    assert dt.load_external("back").W.shape == (8, 6)


def test_benchmark_data_folder_both_forms(monkeypatch, tmp_path):
    from nrsfm.experiments.runner import resolve_data_dir

    folder = _shark_folder(tmp_path / "data")
    assert resolve_data_dir(folder.parent) == folder == resolve_data_dir(folder)
    monkeypatch.setenv("NRSFM_DATA", str(folder.parent))
    assert resolve_data_dir() == folder
    with pytest.raises(FileNotFoundError, match="nowhere does not exist; pass the folder"):
        resolve_data_dir(tmp_path / "nowhere")
