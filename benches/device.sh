#!/bin/sh
# The benchmarks on a machine with a real GPU, from binaries built elsewhere
# (BENCHMARKS.md, "On an H200/H100"). Run in the repository root:
#
#   sh benches/device.sh build              # here: stripped binaries in target/device/
#   sh benches/device.sh run OUT [BENCHES]  # there: results and logs in OUT/
#
# BENCHES defaults to "splat features pose tracker". Criterion's results go
# to OUT/criterion (tabulate them with examples/bench_report.rs). The name
# "profile" instead runs `splattrack track --profile` on a synthetic 100k-
# point blob (40 frames, 640x480): the step per stage, the GPU passes and
# the bytes read back per frame, in OUT/profile_blob100k.txt.
set -eu
case "${1:-}" in
build)
    cargo bench --locked --no-run --message-format=json 2>/dev/null |
        python3 -c '
import json, sys, shutil, os
os.makedirs("target/device", exist_ok=True)
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and "bench" in m["target"]["kind"]:
        shutil.copy(m["executable"], "target/device/" + m["target"]["name"])
'
    cargo build --release --locked
    cp target/release/splattrack target/device/
    strip target/device/*
    ls -la target/device
    ;;
run)
    out=$2
    shift 2
    mkdir -p "$out"
    if [ -d .gl ]; then
        for f in .gl/*.deb; do dpkg -x "$f" /; done
        ldconfig
    fi
    icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    [ -f "$icd" ] && export VK_DRIVER_FILES="$icd"
    export SPLATTRACK_ADAPTER="${SPLATTRACK_ADAPTER:-discrete}"
    export SPLATTRACK_BENCH_1M="${SPLATTRACK_BENCH_1M:-1}"
    export CRITERION_HOME="$out/criterion"
    target/device/splattrack info >"$out/info.txt" 2>&1
    for b in ${*:-splat features pose tracker}; do
        echo "== $b" >&2
        if [ "$b" = profile ]; then
            s=$(mktemp -d)/blob100k
            target/device/splattrack synth --object blob --frames 40 --width 640 --height 480 \
                --points 100000 --out "$s" >"$out/profile.log" 2>&1 &&
                target/device/splattrack track --model "$s/model.ply" --sequence "$s" \
                    --out "$out/blob100k.csv" --profile >"$out/profile_blob100k.txt" 2>&1 ||
                echo "profile failed: see $out/profile.log, $out/profile_blob100k.txt" >&2
            continue
        fi
        target/device/"$b" --bench >"$out/$b.log" 2>&1 || echo "$b failed: see $out/$b.log" >&2
    done
    ;;
*)
    echo "usage: sh benches/device.sh build | run OUT [BENCHES]" >&2
    exit 2
    ;;
esac
