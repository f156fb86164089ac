"""What the Python binding adds to a frame over the Rust API.

    python benches/python_overhead.py SEQUENCE [FRAMES]

Tracks the sequence's frames (camera.json, frames/, keyframes/, init.csv;
e.g. $SPLATTRACK_DATA/visp_rbt_cube, 640x480) through the package, and
compares the wall time of each `Tracker.track` call with the time the Rust
`Tracker::track` inside it measured itself (`TrackResult.time_ms`): the
difference is the binding's own cost (the frame's one copy into the
tracker's buffer, argument checks, the GIL released and taken back, the
result's conversion). The frames are read before timing.
"""

import csv
import os
import statistics
import sys
import time

import numpy as np

import splattrack as st


def read_init(path):
    with open(path, newline="") as f:
        r = next(csv.DictReader(f))
    m = np.eye(4)
    m[:3, :3] = [[float(r[f"r{i}{j}"]) for j in (1, 2, 3)] for i in (1, 2, 3)]
    m[:3, 3] = [float(r["tx"]), float(r["ty"]), float(r["tz"])]
    return m


def main():
    seq = sys.argv[1]
    limit = int(sys.argv[2]) if len(sys.argv) > 2 else None
    cam = st.Camera.from_file(os.path.join(seq, "camera.json"))
    kf = os.path.join(seq, "keyframes")
    trk = st.Tracker(
        st.Model.load(os.path.join(seq, "model.ply")), cam, keyframes=kf if os.path.isdir(kf) else None
    )
    trk.start(read_init(os.path.join(seq, "init.csv")))
    frames = list(st.iter_frames(seq))[:limit]
    walls, inside = [], []
    for frame in frames:
        t0 = time.perf_counter()
        r = trk.track(frame)
        walls.append((time.perf_counter() - t0) * 1e3)
        inside.append(r.time_ms)
    extra = [w - i for w, i in zip(walls, inside)]
    h, w = frames[0].shape[:2]
    print(f"{len(frames)} frames of {w}x{h} on {st.device()}")
    print(f"Tracker.track (Python) {statistics.mean(walls):.2f} ms a frame (median {statistics.median(walls):.2f})")
    print(f"Tracker::track (Rust)  {statistics.mean(inside):.2f} ms a frame (median {statistics.median(inside):.2f})")
    print(
        f"the binding adds {statistics.mean(extra):.3f} ms a frame "
        f"(median {statistics.median(extra):.3f}, max {max(extra):.3f})"
    )


if __name__ == "__main__":
    main()
