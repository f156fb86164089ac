#!/usr/bin/env bash
# Writes the poses one build tracks on the real data (both sequences, every
# mode and modality) and on the demo, so that two builds can be compared
# byte for byte:
#
#   SPLATTRACK_DATA=DIR scripts/same_poses.sh OLD_BIN /tmp/old
#   SPLATTRACK_DATA=DIR scripts/same_poses.sh NEW_BIN /tmp/new
#   scripts/same_poses.sh --compare /tmp/old /tmp/new
set -euo pipefail

if [ "${1:-}" = "--compare" ]; then
    status=0
    for f in $(cd "$2" && find . -name '*.csv' | sort); do
        if ! cmp -s "$2/$f" "$3/$f"; then
            echo "differ: $f"
            status=1
        fi
    done
    n=$(cd "$2" && find . -name '*.csv' | wc -l)
    [ $status = 0 ] && echo "same poses: $n files"
    exit $status
fi

bin=$(realpath "$1")
out=$(realpath -m "$2")
data=${SPLATTRACK_DATA:?set SPLATTRACK_DATA to the real data folder}
mkdir -p "$out"
for seq in visp_rbt_cube visp_rbt_dragon; do
    for mode in kf+it it kf; do
        for cue in texture contour texture,contour; do
            name=$seq.${mode/+/-}.${cue/,/-}
            # A combination the tracker refuses writes no CSV: its log says so.
            "$bin" track --model "$data/$seq/model.ply" --sequence "$data/$seq" \
                --mode "$mode" --modalities "$cue" --out "$out/$name.csv" \
                >"$out/$name.log" 2>&1 || echo "exit $?" >>"$out/$name.log"
        done
    done
done
"$bin" demo --out "$out/demo" >"$out/demo.log" 2>&1
echo "$(find "$out" -name '*.csv' | wc -l) pose files in $out"
