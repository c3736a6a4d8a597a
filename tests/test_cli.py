import subprocess
import sys

import numpy as np
import pytest

import data_tools as dt
from nrsfm.cli import main


def test_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("demo", "run", "mocap"):
        assert cmd in out


def test_console_entry_point_help():
    proc = subprocess.run([sys.executable, "-m", "nrsfm", "run", "--help"],
                          capture_output=True, text=True, check=True)
    assert "INPUT" in proc.stdout.upper() and "--rrd" in proc.stdout


def test_run_writes_results(tmp_path, capsys):
    seq = dt.make_synthetic(F=30, P=20, K=2, seed=4)
    inp = tmp_path / "seq.npz"
    np.savez(inp, W=seq.W, K=2, shapes=seq.shapes, rotations=seq.rotations)
    out = tmp_path / "out.npz"
    assert main(["run", str(inp), "-o", str(out), "--method", "pseudo_inverse",
                 "--given-rotations", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "e3d" in text and str(out) in text
    with np.load(out) as z:
        assert z["shapes"].shape == (30, 3, 20)
        np.testing.assert_allclose(z["rotations"], seq.rotations)
        assert int(z["K"]) == 2


def test_run_errors_are_messages(tmp_path):
    with pytest.raises(SystemExit, match="not found"):
        main(["run", str(tmp_path / "missing.npz")])
    bad = tmp_path / "bad.npz"
    np.savez(bad, X=np.zeros(3))
    with pytest.raises(SystemExit, match="no array 'W'"):
        main(["run", str(bad), "--K", "1"])
    nok = tmp_path / "nok.npz"
    np.savez(nok, W=np.zeros((10, 6)))
    with pytest.raises(SystemExit, match="--K"):
        main(["run", str(nok)])
    nan = tmp_path / "nan.npz"
    np.savez(nan, W=np.full((10, 6), np.nan))
    with pytest.raises(SystemExit, match="NaN|observes 0 points"):
        main(["run", str(nan), "--K", "1"])


def test_mocap_missing_folder_message(tmp_path):
    with pytest.raises(SystemExit, match="not found"):
        main(["mocap", "drink", "--data", str(tmp_path)])
