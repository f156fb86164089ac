#!/usr/bin/env python3
"""Compares two pose CSVs (the tracker's output) frame by frame: the same
frames and statuses, rotations within --deg degrees and translations within
--units model units of each other. Exit 1, naming the first frame that
differs, otherwise prints the largest differences.

    python3 scripts/compare_poses.py a.csv b.csv --deg 0.05 --units 0.0002
"""

import argparse
import csv
import math
import sys


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def rotation(r):
    return [[float(r[f"r{i}{j}"]) for j in (1, 2, 3)] for i in (1, 2, 3)]


def angle_deg(a, b):
    # trace(A^T B) = 1 + 2 cos(angle)
    tr = sum(a[i][j] * b[i][j] for i in range(3) for j in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1) / 2))))


def main():
    p = argparse.ArgumentParser()
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--deg", type=float, required=True)
    p.add_argument("--units", type=float, required=True)
    args = p.parse_args()
    a, b = rows(args.a), rows(args.b)
    if len(a) != len(b) or not a:
        sys.exit(f"{args.a}: {len(a)} rows, {args.b}: {len(b)}")
    worst_r = worst_t = 0.0
    for x, y in zip(a, b):
        f = x["frame"]
        if f != y["frame"] or x["status"] != y["status"]:
            sys.exit(f"frame {f}: {x['status']} / frame {y['frame']}: {y['status']}")
        r = angle_deg(rotation(x), rotation(y))
        t = math.dist([float(x[k]) for k in ("tx", "ty", "tz")], [float(y[k]) for k in ("tx", "ty", "tz")])
        if r > args.deg or t > args.units:
            sys.exit(f"frame {f}: {r:.5f} degrees, {t:.6f} units apart")
        worst_r, worst_t = max(worst_r, r), max(worst_t, t)
    print(f"{len(a)} frames, the same statuses; at most {worst_r:.5f} degrees, {worst_t:.6f} units apart")


if __name__ == "__main__":
    main()
