"""examples/track_video.py runs on a video of the synthetic sequence."""

import subprocess
import sys

import pytest

from conftest import REPO


def test_track_video_example(sequence, tmp_path):
    try:
        import cv2  # noqa: F401
    except ImportError:
        pytest.fail("the example needs OpenCV: pip install opencv-python-headless")
    example = str(REPO / "examples" / "track_video.py")
    video = str(tmp_path / "seq.avi")
    out = str(tmp_path / "outline.avi")
    p = subprocess.run([sys.executable, example, "--frames-to-video", str(sequence / "frames"), video],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    p = subprocess.run(
        [sys.executable, example, "--video", video, "--camera", str(sequence / "camera.json"),
         "--model", str(sequence / "model.ply"), "--keyframes", str(sequence / "keyframes"),
         "--init", str(sequence / "init.csv"), "--out", out],
        capture_output=True, text=True, timeout=600,
    )
    assert p.returncode == 0, p.stderr
    assert "tracked 12 frames (0 lost)" in p.stdout, p.stdout

    import cv2

    cap = cv2.VideoCapture(out)
    n = 0
    while cap.read()[0]:
        n += 1
    assert n == 12
    # The package's own reader of the same video: OpenCV, and the ffmpeg
    # program where OpenCV is missing.
    import splattrack as st

    frames = list(st.iter_frames(video))
    assert len(frames) == 12 and frames[0].shape == (240, 320, 3)
    piped = list(st._frames_ffmpeg(video))
    assert len(piped) == 12 and piped[0].shape == (240, 320, 3)

    assert abs(frames[5].astype(int) - piped[5]).mean() < 3
