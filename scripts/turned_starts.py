#!/usr/bin/env python3
"""Starts turned away from the truth, and how a track from each came back.

    python3 scripts/turned_starts.py write SEQ/init.csv OUT --deg 50
        writes OUT_x.csv, OUT_y.csv, OUT_z.csv, OUT_xy.csv: the first pose
        of SEQ/init.csv turned by DEG degrees about the camera's x, y, z
        and (x+y)/sqrt(2) axes (its translation kept).
    python3 scripts/turned_starts.py score SEQ/poses.csv TRACKED.csv
        prints the first frame reported `tracking` within 5 degrees of the
        ground truth, the largest error of any `tracking` frame, and one
        letter a frame: `t` tracking within 5 degrees, `W` tracking
        farther off, `.` lost.

docs/accuracy.md ("Starts far off") runs it on the real and synthetic
sequences.
"""

import argparse
import math

from compare_poses import angle_deg, rotation, rows

HEADER = "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz"
AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1), "xy": (1, 1, 0)}


def about(axis, deg):
    n = math.sqrt(sum(v * v for v in axis))
    x, y, z = (v / n for v in axis)
    a = math.radians(deg)
    c, s, k = math.cos(a), math.sin(a), 1 - math.cos(a)
    return [
        [c + x * x * k, x * y * k - z * s, x * z * k + y * s],
        [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
        [z * x * k - y * s, z * y * k + x * s, c + z * z * k],
    ]


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def write(args):
    first = rows(args.init)[0]
    for name, axis in AXES.items():
        r = mul(about(axis, args.deg), rotation(first))
        values = [f"{r[i][j]:.9f}" for i in range(3) for j in range(3)]
        values += [first[k] for k in ("tx", "ty", "tz")]
        with open(f"{args.out}_{name}.csv", "w") as f:
            f.write(HEADER + "\n" + ",".join([first["frame"]] + values) + "\n")


def score(args):
    truth = {int(r["frame"]): rotation(r) for r in rows(args.gt)}
    first, worst, line = None, 0.0, ""
    for r in rows(args.tracked):
        k = int(r["frame"])
        err = angle_deg(rotation(r), truth[k])
        if r["status"] == "tracking":
            worst = max(worst, err)
            line += "t" if err < 5 else "W"
            if err < 5 and first is None:
                first = k
        else:
            line += "."
    print(f"first {first} worst {worst:.1f} {line}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    w = sub.add_parser("write")
    w.add_argument("init")
    w.add_argument("out")
    w.add_argument("--deg", type=float, default=50.0)
    s = sub.add_parser("score")
    s.add_argument("gt")
    s.add_argument("tracked")
    args = p.parse_args()
    write(args) if args.what == "write" else score(args)


if __name__ == "__main__":
    main()
