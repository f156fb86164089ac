#!/usr/bin/env python3
"""A point model with a random fraction of its points dropped.

    python3 scripts/drop_points.py MODEL.ply OUT.ply --fraction 0.01 --seed 1

Reads a binary little-endian PLY whose vertices have fixed-size
properties (what `splattrack model` and `synth` write: position, normal,
colour, radius) and writes the same file with about FRACTION of its
vertices left out, chosen by SEED. Another sampling of the same surface:
how much an accuracy figure moves with the model's sampling alone
(docs/performance.md, "One render a frame by the contour" and "A coarser
model").
"""

import argparse
import random
import sys

SIZES = {
    "char": 1, "uchar": 1, "int8": 1, "uint8": 1,
    "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
    "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
    "double": 8, "float64": 8,
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("out")
    ap.add_argument("--fraction", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if not 0.0 <= a.fraction < 1.0:
        sys.exit(f"{a.model}: --fraction {a.fraction} is not in [0, 1)")
    data = open(a.model, "rb").read()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        sys.exit(f"{a.model}: not a PLY file")
    end += len(b"end_header\n")
    header = data[:end].decode("latin1").split("\n")
    if "format binary_little_endian 1.0" not in header:
        sys.exit(f"{a.model}: not a binary little-endian PLY")
    n, record, in_vertex = None, 0, False
    for line in header:
        p = line.split()
        if p[:2] == ["element", "vertex"]:
            n, in_vertex = int(p[2]), True
        elif p[:1] == ["element"]:
            in_vertex = False
        elif p[:1] == ["property"] and in_vertex:
            if p[1] == "list" or p[1] not in SIZES:
                sys.exit(f"{a.model}: vertex property '{line}' is not of fixed size")
            record += SIZES[p[1]]
    if n is None or end + n * record > len(data):
        sys.exit(f"{a.model}: no vertex element, or fewer bytes than it declares")
    body = data[end:end + n * record]
    rng = random.Random(a.seed)
    keep = [i for i in range(n) if rng.random() >= a.fraction]
    out = b"".join(body[i * record:(i + 1) * record] for i in keep)
    header = [
        f"element vertex {len(keep)}" if line.startswith("element vertex") else line
        for line in header
    ]
    with open(a.out, "wb") as f:
        f.write("\n".join(header).encode("latin1") + out + data[end + n * record:])
    print(f"{a.out}: {len(keep)} of {n} points")


if __name__ == "__main__":
    main()
