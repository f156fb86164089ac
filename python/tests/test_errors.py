"""Every documented exception, with the command's one-line messages."""

import os
import subprocess
import sys

import numpy as np
import pytest
import splattrack as st

from conftest import read_poses


@pytest.fixture(scope="module")
def setup(sequence):
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    trk = st.Tracker(model, cam, keyframes=sequence / "keyframes", modalities="texture")
    trk.start(read_poses(sequence / "init.csv")[0][1])
    return cam, model, trk


def test_hierarchy():
    for e in (st.ModelError, st.InputError, st.GpuError, st.TrackError):
        assert issubclass(e, st.Error) and issubclass(e, Exception)
    assert not issubclass(st.Error, ValueError)


@pytest.mark.parametrize(
    "frame, message",
    [
        (np.zeros((240, 320, 3), np.float32), "dtype float32: expected uint8"),
        (np.zeros((240, 320, 4), np.uint8), "4 channels"),
        (np.zeros((120, 160, 3), np.uint8), "(120, 160, 3), the camera is 320x240"),
        (np.zeros((240, 320), np.uint16), "expected uint8"),
        (np.zeros(10, np.uint8), "shape (10,)"),
        ([[1, 2, 3]], "must be a numpy array, not list"),
    ],
)
def test_bad_frames_are_value_errors(setup, frame, message):
    _, _, trk = setup
    with pytest.raises(ValueError) as e:
        trk.track(frame)
    assert message in str(e.value)


def test_non_contiguous_frames_track(setup, sequence):
    _, _, trk = setup
    frame = next(st.iter_frames(sequence))
    bgr = frame[:, :, ::-1]
    assert not bgr.flags["C_CONTIGUOUS"]
    trk.track(np.ascontiguousarray(bgr[:, :, ::-1]))
    trk.track(bgr[:, :, ::-1])  # a view: strided, but the same bytes


@pytest.mark.parametrize(
    "pose, message",
    [
        (np.eye(3), "3x3: expected a 4x4"),
        (np.full((4, 4), np.nan), "NaN"),
        ("x", "must be a 4x4 array"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "pose"),
    ],
)
def test_bad_poses_are_value_errors(setup, pose, message):
    _, _, trk = setup
    with pytest.raises(ValueError) as e:
        trk.start(pose)
    assert message in str(e.value)


def test_pose_out_of_view_is_a_value_error(setup):
    _, _, trk = setup
    behind = np.eye(4)
    behind[2, 3] = -1.0
    with pytest.raises(ValueError, match="behind the camera or outside the image"):
        trk.start(behind)


def test_bad_settings_are_value_errors(sequence):
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    with pytest.raises(ValueError, match=r"^kf_search=-1: must be"):
        st.Tracker(model, cam, kf_search=-1.0)
    with pytest.raises(ValueError, match=r"max_corners=0: must be 1..=100000"):
        st.Tracker(model, cam, max_corners=0)
    with pytest.raises(ValueError, match="mode"):
        st.Tracker(model, cam, mode="fast")
    with pytest.raises(ValueError, match="modalities"):
        st.Tracker(model, cam, modalities="sound")
    with pytest.raises(TypeError, match="unexpected keyword argument"):
        st.Tracker(model, cam, kf_serch=3)
    with pytest.raises(ValueError, match="impossible camera"):
        st.Camera(-1, 500, 160, 120, 320, 240)


def test_file_errors(sequence, tmp_path):
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    with pytest.raises(st.ModelError, match="nothing.ply"):
        st.Model.load(tmp_path / "nothing.ply")
    bad = tmp_path / "bad.ply"
    bad.write_text("ply\nformat nonsense\n")
    with pytest.raises(st.ModelError, match="bad.ply"):
        st.Model.load(bad)
    with pytest.raises(st.InputError, match="nothing.json"):
        st.Camera.from_file(tmp_path / "nothing.json")
    with pytest.raises(st.InputError, match="not a keyframe store file nor a directory with poses.csv"):
        st.Tracker(model, cam, keyframes=tmp_path)
    with pytest.raises(st.InputError):
        st.read_image(tmp_path / "nothing.png")
    with pytest.raises(st.InputError):
        list(st.iter_frames(tmp_path / "nothing.mp4"))


def test_track_errors(sequence, tmp_path):
    """A KF mode, or a search, with nothing to texture the views."""
    cam = st.Camera.from_file(sequence / "camera.json")
    mesh = st.Model.load(sequence / "mesh.obj", points=5000)
    assert not mesh.has_colors
    with pytest.raises(st.TrackError, match="mode kf needs keyframes or a model with colours"):
        st.Tracker(mesh, cam, mode="kf")
    trk = st.Tracker(mesh, cam)
    assert trk.mode == "it"
    frame = next(st.iter_frames(sequence))
    with pytest.raises(st.TrackError, match="search .no initial pose. needs keyframes"):
        trk.track(frame)


def test_gpu_error_without_an_adapter():
    """An adapter that is not there: GpuError, not a crash, where a GPU is
    asked for; "auto" falls back to the CPU device."""
    code = (
        "import splattrack as st\n"
        "assert 'CPU' in st.device(), st.device()\n"
        "try:\n"
        "    st.device('gpu')\n"
        "except st.GpuError as e:\n"
        "    print('GpuError:', e)\n"
    )
    env = dict(os.environ, SPLATTRACK_ADAPTER="no-such-adapter")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("GpuError: "), p.stdout + p.stderr


def test_auto_takes_the_cpu_device_over_a_software_adapter():
    """As the command line: "auto" runs on the CPU device where the only
    adapter is a software one nobody named (lavapipe: about 3x slower),
    and on that adapter where $SPLATTRACK_ADAPTER names it."""
    code = (
        "import splattrack as st\n"
        "gpu = st.device('gpu')\n"
        "print(gpu)\n"
        "print(st.device())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "SPLATTRACK_ADAPTER"}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    if p.returncode != 0 or "(Cpu," not in p.stdout.splitlines()[0]:
        pytest.skip("a hardware GPU adapter is the default here: auto takes it")
    assert "CPU" in p.stdout.splitlines()[1], p.stdout
    named = dict(os.environ, SPLATTRACK_ADAPTER="cpu")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=named, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines()[1] == p.stdout.splitlines()[0], p.stdout
