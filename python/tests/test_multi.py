"""Several objects through Python: splattrack.MultiTracker gives the
command's poses for every object, frame for frame."""

import pytest
import splattrack as st

from conftest import read_poses, run


def fmt(pose):
    """A pose as the command's CSV writes it (9 decimals, row-major R then t)."""
    vals = [pose[i, j] for i in range(3) for j in range(3)] + [pose[i, 3] for i in range(3)]
    return ",".join(f"{v:.9f}" for v in vals).replace("-0.000000000", "0.000000000")


def test_two_objects_give_the_command_poses(sequence, tmp_path):
    """The sequence's object twice, named a and b, each started at the
    sequence's first pose: the command's two-object file, row for row."""
    init = sequence / "init.csv"
    model = sequence / "model.ply"
    out = tmp_path / "poses.csv"
    run("track", "--sequence", str(sequence), "--model", f"a={model}", "--model",
        f"b={model}", "--init", str(init), "--init", str(init),
        "--keyframes", str(sequence / "keyframes"), "--keyframes", str(sequence / "keyframes"),
        "--out", str(out))
    with open(out) as f:
        assert f.readline().startswith("object,frame,")
    cli = read_poses(out)
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(model), cam, keyframes=sequence / "keyframes")
    multi = st.MultiTracker({"a": trk, "b": trk})
    assert multi.names == ["a", "b"] and len(multi) == 2
    assert multi.poses == {"a": None, "b": None}
    start = read_poses(init)[0][1]
    multi.start({"a": start, "b": start})
    rows = []
    for i, frame in enumerate(st.iter_frames(sequence)):
        results = multi.track(frame)
        assert list(results) == ["a", "b"]
        rows += [(name, r) for name, r in results.items()]
    assert len(rows) == len(cli) == 24
    for (name, r), (_, pose, row) in zip(rows, cli):
        assert row["object"] == name
        assert fmt(r.pose) == fmt(pose), row["frame"]
        assert r.status == row["status"] and r.cues == row["cues"]
    assert fmt(multi.poses["b"]) == fmt(rows[-1][1].pose)


def test_bad_objects_are_refused(sequence):
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam)
    with pytest.raises(ValueError, match="two objects are named"):
        st.MultiTracker([("a", trk), ("a", trk)])
    with pytest.raises(ValueError, match="no object"):
        st.MultiTracker({})
    with pytest.raises(ValueError, match="dict of name"):
        st.MultiTracker(trk)
    multi = st.MultiTracker([("a", trk)])
    with pytest.raises(ValueError, match='no object named "b"'):
        multi.start({"b": read_poses(sequence / "init.csv")[0][1]})
