#!/usr/bin/env python3
"""The host's share of `splattrack track`'s frame loop, from a perf profile.

On lavapipe the "GPU" runs on the same CPU, as JIT-compiled shader code
whose samples cannot be unwound into the tracker: the tracking thread's
samples inside `Tracker::track` are what the host itself spends a frame (encoding and
submitting GPU work, uploads, readback waits' CPU time, the host's own
arithmetic), which it would spend with any GPU (docs/performance.md, "The GPU
loop's host work"). Record with call graphs first, e.g.

    perf record -F 999 --call-graph dwarf,32768 -o perf.data \\
        target/release/splattrack track --model M --sequence S \\
        --feature-backend gpu --resident on --out /tmp/p.csv
    python3 benches/host_work.py perf.data 999 FRAMES

(FRAMES: the frames tracked). Prints ms a frame per category, the
GPU API calls behind the submission category, and wgpu's API calls
wherever they are made (the frame's intake records and submits GPU work
too). The contour's colour
learning runs on a thread of its own while the next frame's texture steps
run (src/tracker/contour/learner.rs); its time is printed apart, not in the host's
total. Needs perf; standard library only.
"""

import collections
import re
import signal
import subprocess
import sys

CATEGORIES = [
    ("the frame in: grey, packing, uploads, crops, its Harris window",
     r"from_rgb8|pack_with_holes|GpuGrey::upload|FrameIntake|Placed::crop|frame_corners"),
    ("contour on the host: colours, outline, normals, lines", r"contour::"),
    ("pose solves (IRLS)", r"pose::irls|pose::refine|Tracker::refine"),
    ("GPU work's submission: wgpu, the driver, readback waits",
     r"wgpu|read_buffer|map_read|poll"),
]

# The contour's colour learning on its own thread (src/tracker/contour/learner.rs,
# named so; perf keeps 15 characters): not on the frame's path, reported
# apart.
LEARNER = "splattrack-colours"[:15]


def samples(path, threads=None):
    """Yields each sample's call chain, leaf first, as (symbol, dso); with
    a list `threads`, appends each sample's thread name to it."""
    p = subprocess.Popen(["perf", "script", "-i", path, "-F", "comm,ip,sym,dso"],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    stack = []
    for line in p.stdout:
        if not line.strip() or line[0] not in " \t":
            if stack:
                yield stack
            stack = []
            if line.strip() and threads is not None:
                threads.append(line.strip())
            continue
        m = re.match(r"\s+([0-9a-f]+)\s+(.*)\s+\((.*)\)\s*$", line)
        if m:
            stack.append((m.group(2), m.group(3).split("/")[-1]))
    if stack:
        yield stack
    if p.wait() != 0:
        sys.exit(f"perf script failed on {path}")


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    path, hz, frames = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    per_frame = 1e3 / hz / frames
    total, api, other = collections.Counter(), collections.Counter(), collections.Counter()
    # wgpu's API calls wherever they are made (a category above takes a
    # sample whole: the frame's intake records and submits GPU work too).
    anywhere = collections.Counter()
    lib = collections.Counter()
    aside = 0
    threads = []
    for stack in samples(path, threads):
        syms = [s for s, _ in stack]
        if threads and threads[-1] == LEARNER:
            aside += 1
            continue
        if not any("Tracker::track" in s for s in syms):
            continue
        joined = " | ".join(syms)
        outer = [s for s in syms if re.match(r"<?wgpu::api", s)]
        if outer:
            anywhere[re.sub(r"<.*?>", "", outer[-1])] += 1
        for name, pattern in CATEGORIES:
            if re.search(pattern, joined):
                total[name] += 1
                if name.startswith("GPU work"):
                    calls = [s for s in syms if re.match(r"<?wgpu::api", s)]
                    api[re.sub(r"<.*?>", "", calls[-1]) if calls else "(other)"] += 1
                    leaf = stack[0][1]
                    lib["splattrack (inlined)" if leaf == "inlined" else leaf] += 1
                break
        else:
            total["other host work"] += 1
            own = next((s for s in syms if "splattrack::" in s), syms[0])
            other[re.sub(r"<.*?>", "", own)[:90]] += 1
    host = sum(total.values())
    print(f"ms a frame, {frames} frames, from {path}:")
    for name, n in total.most_common():
        print(f"  {n * per_frame:7.2f}  {name}")
    print(f"  {host * per_frame:7.2f}  the host in all")
    print(f"  {aside * per_frame:7.2f}  besides, on the colour learner's thread (beside the next frame's steps)")
    print("GPU API calls behind the submission:")
    for name, n in api.most_common(6):
        print(f"  {n * per_frame:7.2f}  {name}")
    print("the submission by library (lavapipe's and the kernel's share")
    print("is what a GPU's driver would replace with its own):")
    for name, n in lib.most_common(6):
        print(f"  {n * per_frame:7.2f}  {name}")
    print(f"wgpu's API calls, whatever the category: {sum(anywhere.values()) * per_frame:.2f}")
    for name, n in anywhere.most_common(6):
        print(f"  {n * per_frame:7.2f}  {name}")
    print("other host work, by function:")
    for name, n in other.most_common(6):
        print(f"  {n * per_frame:7.2f}  {name}")


if __name__ == "__main__":
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # quiet under `| head`
    main()
