"""Tracking through Python gives the command's poses, frame for frame."""

import numpy as np
import pytest
import splattrack as st

from conftest import read_poses


def fmt(pose):
    """A pose as the command's CSV writes it (9 decimals, row-major R then t)."""
    vals = [pose[i, j] for i in range(3) for j in range(3)] + [pose[i, 3] for i in range(3)]
    return ",".join(f"{v:.9f}" for v in vals)


def test_poses_identical_to_the_command(sequence, cli_poses):
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    trk = st.Tracker(model, cam, keyframes=sequence / "keyframes")
    trk.start(read_poses(sequence / "init.csv")[0][1])
    results = [r for _, r in st.track_frames(trk, sequence)]
    assert len(results) == len(cli_poses) == 12
    assert trk.mode == "kf+it"
    assert trk.modalities == "texture"
    for i, (r, (_, pose, row)) in enumerate(zip(results, cli_poses)):
        assert fmt(r.pose).replace("-0.000000000", "0.000000000") == fmt(pose).replace(
            "-0.000000000", "0.000000000"
        ), f"frame {i}"
        assert r.status == row["status"], f"frame {i}"
        assert r.inliers == int(row["inliers"]), f"frame {i}"
        assert r.cues == row["cues"]
        assert r.reason is None
        assert r.pose.dtype == np.float64 and r.pose.shape == (4, 4)
        assert r.time_ms > 0


def test_accuracy_against_ground_truth(sequence):
    """Independent of the command: the synthesiser's own poses."""
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    gt = read_poses(sequence / "poses.csv")
    trk.start(gt[0][1])
    rot = []
    for (_, r), (_, truth, _) in zip(st.track_frames(trk, sequence), gt):
        assert r.status == "tracking"
        assert np.linalg.norm(r.pose[:3, 3] - truth[:3, 3]) < 0.005  # 5 mm at 0.55 m
        cos = (np.trace(r.pose[:3, :3].T @ truth[:3, :3]) - 1) / 2
        rot.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    # The command's figures on this sequence: 0.45 degrees mean, 2.1 at most.
    assert len(rot) == 12 and np.mean(rot) < 1.0 and max(rot) < 3.0, rot


def test_the_cpu_device_tracks_as_the_gpu(sequence, cli_poses):
    """device="cpu": no GPU object, the same statuses and poses within
    1e-4 (the host's sums in another order than the GPU's)."""
    assert "CPU" in st.device("cpu")
    with pytest.raises(ValueError):
        st.device("lavapipe")
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    trk = st.Tracker(model, cam, keyframes=sequence / "keyframes", device="cpu")
    trk.start(read_poses(sequence / "init.csv")[0][1])
    results = [r for _, r in st.track_frames(trk, sequence)]
    assert len(results) == len(cli_poses) == 12
    for i, (r, (_, pose, row)) in enumerate(zip(results, cli_poses)):
        assert r.status == row["status"], f"frame {i}"
        assert np.abs(r.pose - pose).max() < 1e-4, f"frame {i}"


def test_keyframe_pairs_and_grey_frames(sequence, cli_poses):
    """A list of (image, pose) pairs builds the folder's store (the
    command's poses); grey frames track."""
    cam = st.Camera.from_file(sequence / "camera.json")
    model = st.Model.load(sequence / "model.ply")
    rows = read_poses(sequence / "keyframes" / "poses.csv")
    kf = [(st.read_image(sequence / "keyframes" / name), pose) for name, pose, _ in rows]
    trk = st.Tracker(model, cam, keyframes=kf)
    assert trk.keyframes == 12
    trk.start(read_poses(sequence / "init.csv")[0][1])
    frames = list(st.iter_frames(sequence))[:4]
    for i, frame in enumerate(frames):
        assert fmt(trk.track(frame).pose) == fmt(cli_poses[i][1]), f"frame {i}"
    trk = st.Tracker(model, cam, keyframes=kf, modalities="texture")
    gt = read_poses(sequence / "poses.csv")
    trk.start(gt[0][1])
    for frame, (_, truth, _) in zip(frames, gt):
        r = trk.track(frame.mean(axis=2).astype(np.uint8))
        assert r.status == "tracking", r.reason
        assert np.linalg.norm(r.pose[:3, 3] - truth[:3, 3]) < 0.005


def test_render_covers_the_object(sequence):
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    pose = read_poses(sequence / "poses.csv")[0][1]
    colour, depth, mask = trk.render(pose)
    assert colour.shape == (240, 320, 3) and colour.dtype == np.uint8
    assert depth.shape == (240, 320) and depth.dtype == np.float32
    assert mask.shape == (240, 320) and mask.dtype == np.bool_
    assert 0.02 * mask.size < mask.sum() < 0.9 * mask.size
    # Depth about the object's distance (0.55 m, diameter 0.33 m).
    assert np.all(np.isfinite(depth[mask])) and np.all(np.isnan(depth[~mask]))
    assert 0.3 < np.median(depth[mask]) < 0.8
    # The view's colours are the frame's where the object is (the
    # synthesiser drew frame 0 at this pose).
    frame = st.iter_frames(sequence).__next__().astype(float)
    diff = np.abs(colour.astype(float) - frame)[mask].mean()
    assert diff < 25, diff
    # Where the object is, per the splatter's mask: its centroid is the
    # projection of the model's centre at this pose.
    ys, xs = np.nonzero(mask)
    c = pose[:3, :3] @ st.Model.load(sequence / "model.ply").positions.mean(axis=0) + pose[:3, 3]
    u, v = cam.fx * c[0] / c[2] + cam.cx, cam.fy * c[1] / c[2] + cam.cy
    assert abs(xs.mean() - u) < 10 and abs(ys.mean() - v) < 10


def test_search_without_start(sequence):
    """Without start() the tracker searches for the object."""
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    assert trk.pose is None
    truth = read_poses(sequence / "poses.csv")[0][1]
    r = trk.track(next(st.iter_frames(sequence)))
    # Found at once: the object in the open, textured by its keyframes.
    assert r.status == "tracking", r.reason
    assert np.linalg.norm(r.pose[:3, 3] - truth[:3, 3]) < 0.005
    assert np.allclose(trk.pose, r.pose)


def test_rendering_between_frames_changes_no_pose(sequence, cli_poses):
    """The outline drawn each frame (as the example does) leaves the poses alone."""
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    trk.start(read_poses(sequence / "init.csv")[0][1])
    for (i, r), (_, pose, _) in zip(st.track_frames(trk, sequence), cli_poses):
        assert fmt(r.pose) == fmt(pose), f"frame {i}"
        trk.render(r.pose)


def test_lost_before_found_has_no_pose(sequence):
    """A frame without the object, before any pose: lost, not found, NaN."""
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    r = trk.track(np.full((240, 320, 3), 128, np.uint8))
    assert r.status == "lost" and r.reason == "object not found in the image"
    assert np.isnan(r.pose).all() and trk.pose is None

