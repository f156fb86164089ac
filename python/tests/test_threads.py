"""The GIL is released while a frame is tracked and a view rendered: a
second Python thread makes progress throughout the call."""

import random
import sys
import threading
import time

import splattrack as st

from conftest import read_poses


def share_of_call_another_thread_ran(call) -> float:
    """Runs `call()` while a second thread counts; the share of the call's
    milliseconds in which that thread ran. Were the GIL held through the
    call, it could run only in the switch interval (5 ms) around it."""
    stamps = []
    done = threading.Event()

    def count():
        n = 0
        while not done.is_set():
            n += 1
            if n % 200 == 0:
                stamps.append(time.perf_counter())

    # A short switch interval: a thread holding the GIL through the call
    # would leave the counter a millisecond or two at its ends.
    interval = sys.getswitchinterval()
    sys.setswitchinterval(0.001)
    t = threading.Thread(target=count)
    t.start()
    try:
        time.sleep(0.02)
        t0 = time.perf_counter()
        call()
        t1 = time.perf_counter()
    finally:
        done.set()
        t.join()
        sys.setswitchinterval(interval)
    elapsed_ms = (t1 - t0) * 1e3
    assert elapsed_ms > 30, f"the call took {elapsed_ms:.1f} ms: too fast to tell"
    busy = {int((s - t0) * 1e3) for s in stamps if t0 <= s <= t1}
    return len(busy) / elapsed_ms


def test_the_measure_sees_a_call_that_holds_the_gil():
    """sorted() holds the GIL throughout: the counter barely runs."""
    data = [random.random() for _ in range(1_500_000)]
    share = share_of_call_another_thread_ran(lambda: sorted(data))
    assert share < 0.05, share


def test_another_thread_runs_while_tracking_and_rendering(sequence):
    cam = st.Camera.from_file(sequence / "camera.json")
    trk = st.Tracker(st.Model.load(sequence / "model.ply"), cam, keyframes=sequence / "keyframes")
    trk.start(read_poses(sequence / "init.csv")[0][1])
    frames = list(st.iter_frames(sequence))
    trk.track(frames[0])
    # All the other frames in one call: long enough to tell on any device
    # (a frame of this small sequence takes some 20 ms on the CPU device).
    share = share_of_call_another_thread_ran(lambda: [trk.track(f) for f in frames[1:]])
    assert share > 0.1, share
    pose = read_poses(sequence / "poses.csv")[3][1]
    # A larger view than the frame's region: the whole image (a few ms
    # each on the CPU device: ten of them).
    share = share_of_call_another_thread_ran(lambda: [trk.render(pose) for _ in range(10)])
    assert share > 0.1, share
