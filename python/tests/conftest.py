"""Fixtures: the splattrack command (built by cargo) and a short synthetic
sequence it writes, with the command's own poses to compare against."""

import csv
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def splattrack_bin() -> str:
    """The command: $SPLATTRACK_BIN, else cargo's release build."""
    candidates = [os.environ.get("SPLATTRACK_BIN")]
    target = os.environ.get("CARGO_TARGET_DIR")
    if target:
        candidates.append(os.path.join(target, "release", "splattrack"))
    candidates.append(str(REPO / "target" / "release" / "splattrack"))
    for c in candidates:
        if c and os.path.isfile(c):
            return c
    found = shutil.which("splattrack")
    if found:
        return found
    pytest.fail(
        "the splattrack command is needed to make the test sequence: "
        "run `cargo build --release` (or set SPLATTRACK_BIN)"
    )


def run(*args: str) -> None:
    p = subprocess.run([splattrack_bin(), *args], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, f"splattrack {' '.join(args)} failed:\n{p.stderr}"


def read_poses(path):
    """The rows of a pose CSV: (frame, 4x4 pose, row as a dict)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    out = []
    for r in rows:
        m = np.eye(4)
        m[:3, :3] = np.array([float(r[f"r{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3)
        m[:3, 3] = [float(r["tx"]), float(r["ty"]), float(r["tz"])]
        out.append((r["frame"], m, r))
    return out


@pytest.fixture(scope="session")
def sequence(tmp_path_factory):
    """A 12-frame 320x240 synthetic sequence with keyframes and init.csv."""
    d = tmp_path_factory.mktemp("seq") / "blob"
    run("synth", "--frames", "12", "--width", "320", "--height", "240",
        "--points", "20000", "--out", str(d))
    return d


@pytest.fixture(scope="session")
def cli_poses(sequence, tmp_path_factory):
    """The command's poses on the sequence, with its defaults."""
    out = tmp_path_factory.mktemp("cli") / "poses.csv"
    run("track", "--model", str(sequence / "model.ply"), "--sequence", str(sequence),
        "--out", str(out))
    return read_poses(out)
