"""nrsfm.io: exact output names, atomic replacement, checks before the computation."""

import os
import pickle
import zipfile

import numpy as np
import pytest

from nrsfm.io import atomic_output, check_output_path, load_npz, save_npz, write_text


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
    if os.path.isdir("/sys"):  # read-only even for root (Linux)
        with pytest.raises(PermissionError, match="not writable"):
            check_output_path("/sys/a.npz")
    assert os.listdir(tmp_path) == []  # the probe leaves nothing behind


def test_write_text_is_atomic(tmp_path):
    target = tmp_path / "t.json"
    assert write_text(target, "{}") == target and target.read_text() == "{}"
    with pytest.raises(TypeError):
        write_text(target, None)  # fails while writing: old file kept
    assert target.read_text() == "{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def test_load_npz_reads_the_arrays(tmp_path):
    path = save_npz(tmp_path / "in.npz", W=np.arange(6.0).reshape(2, 3), K=np.int64(2))
    data = load_npz(path)
    assert sorted(data) == ["K", "W"] and data["K"] == 2
    np.testing.assert_array_equal(data["W"], np.arange(6.0).reshape(2, 3))


def _unreadable(tmp_path):
    """name -> (file, fragment of the message)."""
    good = save_npz(tmp_path / "good.npz", compressed=False, W=np.zeros((40, 30)))
    files = {
        "text": b"W = 1, 2, 3\n",
        "empty": b"",
        "pickle": pickle.dumps({"W": [1]}),
        "binary": bytes(range(255, 0, -1)),
        "truncated": good.read_bytes()[:300],
    }
    for name, raw in files.items():
        (tmp_path / f"{name}.npz").write_bytes(raw)
    np.save(tmp_path / "one.npy", np.zeros(3))
    np.savez(tmp_path / "object.npz", W=np.array([1, "a", None], dtype=object))
    with zipfile.ZipFile(tmp_path / "zip.npz", "w") as z:
        z.writestr("W.txt", "1 2 3")
    out = {
        "text": "it is a text file (it starts with 'W = 1, 2, 3')",
        "empty": "is empty",
        "pickle": "it is a Python pickle (never loaded)",
        "binary": "a binary file of an unknown kind",
        "truncated": "corrupt .npz archive",
        "one.npy": "it is a .npy file (one array)",
        "object": "is an object array",
        "zip": "member 'W.txt' is not a NumPy array",
    }
    return {k: (tmp_path / (k if k.endswith(".npy") else f"{k}.npz"), v) for k, v in out.items()}


@pytest.mark.parametrize(
    "case", ["text", "empty", "pickle", "binary", "truncated", "one.npy", "object", "zip"]
)
def test_load_npz_unreadable_files_plain_messages(tmp_path, case):
    """A plain one-line ValueError naming the file; never numpy's advice to unpickle."""
    path, fragment = _unreadable(tmp_path)[case]
    with pytest.raises(ValueError) as info:
        load_npz(path, "input", expected="an .npz with an array W")
    msg = str(info.value)
    assert fragment in msg and str(path) in msg and "\n" not in msg
    assert "allow_pickle" not in msg and "pickle.load" not in msg and "unsafe" not in msg


def test_load_npz_missing_file_and_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_npz(tmp_path / "nope.npz")
    with pytest.raises(ValueError, match="is a folder; expected an .npz archive"):
        load_npz(tmp_path)


def test_a_killed_write_leaves_no_temporary_file_after_the_next_one(tmp_path):
    """A process killed while writing leaves its temporary file; the next write of the same
    output removes it (not the temporary file of a process that still runs)."""
    import subprocess
    import sys

    out = tmp_path / "out.npz"
    code = (
        "import os, sys\n"
        "from nrsfm.io import atomic_output\n"
        "with atomic_output(sys.argv[1]) as tmp:\n"
        "    open(tmp, 'wb').write(b'partial')\n"
        "    os._exit(9)\n"  # killed half-way: no clean-up runs
    )
    subprocess.run([sys.executable, "-c", code, str(out)], check=False)
    assert len(list(tmp_path.glob(".out.npz.*.tmp.npz"))) == 1
    alive = tmp_path / f".out.npz.{os.getpid()}.x.tmp.npz"  # this process: still running
    alive.write_bytes(b"")
    save_npz(out, a=np.zeros(3))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["out.npz", alive.name])
