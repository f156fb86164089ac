"""Tracks an object through a video read with OpenCV and draws its outline.

    python examples/track_video.py --video clip.mp4 --camera camera.json \
        --model object.ply --keyframes keyframes/ --init init.csv --out outline.mp4

Without --init the object is searched for in the first frames. Each frame
of the output has the model's outline at the tracked pose: green while
tracking, red when lost (the last good pose). From a sequence made by
`splattrack synth` (docs/python.md):

    splattrack synth --frames 60 --out seq
    python examples/track_video.py --frames-to-video seq/frames seq.avi
    python examples/track_video.py --video seq.avi --camera seq/camera.json \
        --model seq/model.ply --keyframes seq/keyframes --init seq/init.csv --out outline.avi
"""

import argparse
import csv
import sys

import cv2
import numpy as np

import splattrack as st


def read_init(path):
    """The first row of a pose CSV as a 4x4 matrix."""
    with open(path, newline="") as f:
        r = next(csv.DictReader(f))
    m = np.eye(4)
    m[:3, :3] = [[float(r[f"r{i}{j}"]) for j in (1, 2, 3)] for i in (1, 2, 3)]
    m[:3, 3] = [float(r["tx"]), float(r["ty"]), float(r["tz"])]
    return m


def frames_to_video(folder, out, fps=30):
    """Writes the images of a folder as a video (MJPG), for trying the example."""
    writer = None
    for path in st.list_images(folder):
        bgr = cv2.imread(str(path))
        if writer is None:
            h, w = bgr.shape[:2]
            writer = cv2.VideoWriter(out, cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
        writer.write(bgr)
    if writer is None:
        sys.exit(f"{folder}: no images")
    writer.release()
    print(f"wrote {out}")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--video")
    p.add_argument("--camera")
    p.add_argument("--model")
    p.add_argument("--keyframes")
    p.add_argument("--init")
    p.add_argument("--out", default="outline.avi")
    p.add_argument("--frames-to-video", nargs=2, metavar=("FOLDER", "VIDEO"))
    a = p.parse_args()
    if a.frames_to_video:
        frames_to_video(*a.frames_to_video)
        return
    if not (a.video and a.camera and a.model):
        p.error("--video, --camera and --model are needed")

    try:
        cam = st.Camera.from_file(a.camera)
        trk = st.Tracker(st.Model.load(a.model), cam, keyframes=a.keyframes)
        if a.init:
            trk.start(read_init(a.init))
    except (st.Error, ValueError) as e:
        sys.exit(f"error: {e}")

    cap = cv2.VideoCapture(a.video)
    if not cap.isOpened():
        sys.exit(f"error: {a.video}: OpenCV cannot open it")
    fps = cap.get(cv2.CAP_PROP_FPS) or 30
    out = cv2.VideoWriter(a.out, cv2.VideoWriter_fourcc(*"MJPG"), fps, (cam.width, cam.height))
    lost = n = 0
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        r = trk.track(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        _, _, mask = trk.render(r.pose)
        outline, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        colour = (0, 200, 0) if r.status == "tracking" else (0, 0, 255)
        cv2.drawContours(bgr, outline, -1, colour, 2)
        label = f"{n} {r.status} {r.inliers} inliers {r.time_ms:.0f} ms"
        cv2.putText(bgr, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1)
        out.write(bgr)
        lost += r.status == "lost"
        n += 1
    out.release()
    print(f"tracked {n} frames ({lost} lost) on {st.device()}: {a.out}")


if __name__ == "__main__":
    main()
