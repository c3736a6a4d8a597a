"""nrsfm.io: exact output names, atomic replacement, checks before the computation."""

import os

import numpy as np
import pytest

from nrsfm.io import atomic_output, check_output_path, save_npz, write_text


def test_save_npz_writes_exactly_the_name_given(tmp_path):
    out = save_npz(tmp_path / "result.dat", a=np.arange(3))
    assert out == tmp_path / "result.dat"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.dat"]
    with np.load(out) as z:
        np.testing.assert_array_equal(z["a"], np.arange(3))


def test_failure_inside_the_block_leaves_the_old_file(tmp_path):
    target = tmp_path / "x.rrd"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            assert tmp.parent == tmp_path and tmp.suffix == ".rrd"
            tmp.write_bytes(b"half")
            raise RuntimeError("boom")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]


def test_replacement_keeps_the_permissions(tmp_path):
    target = tmp_path / "x.npz"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)
    save_npz(target, a=np.zeros(2))
    assert (target.stat().st_mode & 0o777) == 0o640
    fresh = save_npz(tmp_path / "new.npz", a=np.zeros(2))
    mask = os.umask(0)
    os.umask(mask)
    assert (fresh.stat().st_mode & 0o777) == 0o666 & ~mask


def test_check_output_path(tmp_path):
    assert check_output_path(tmp_path / "a.npz") == tmp_path / "a.npz"
    with pytest.raises(ValueError, match="existing folder"):
        check_output_path(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        check_output_path(tmp_path / "no" / "a.npz")
    if os.path.isdir("/sys"):                  # read-only even for root (Linux)
        with pytest.raises(PermissionError, match="not writable"):
            check_output_path("/sys/a.npz")
    assert os.listdir(tmp_path) == []          # the probe leaves nothing behind


def test_write_text_is_atomic(tmp_path):
    target = tmp_path / "t.json"
    assert write_text(target, "{}") == target and target.read_text() == "{}"
    with pytest.raises(TypeError):
        write_text(target, None)                 # fails while writing: old file kept
    assert target.read_text() == "{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]
