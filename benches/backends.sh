#!/usr/bin/env bash
# The per-back-end table of docs/performance.md ("Every back end"): ms a
# frame of `splattrack track` (mean over the frames, median of RUNS runs)
# and where one more run with `--profile` spends it, for the real cube and
# dragon (default flags) and synthetic objects of 100k and 1M points (the
# textured blob, the untextured `plain`; default flags: the cues are
# chosen per object), on each back end given.
#
#   bash benches/backends.sh [BACKENDS]    # default: "cpu lavapipe"
#
# Back ends: `cpu` (the CPU device, `--compute cpu`), `lavapipe`
# (`--compute gpu` on `SPLATTRACK_ADAPTER=cpu`), `gpu` (`--compute gpu`
# on the default adapter: a GPU machine). Needs $SPLATTRACK_DATA (the real
# sequences) and a release build; the synthetic sequences go to $WORK
# (default /tmp/splattrack-backends). FRAMES_1M frames of the 1M-point
# sequences are tracked (default 30: lavapipe takes about a second a
# frame there). Prints a markdown table; logs stay in $WORK.
set -euo pipefail
bin=${BIN:-target/release/splattrack}
work=${WORK:-/tmp/splattrack-backends}
runs=${RUNS:-3}
frames_1m=${FRAMES_1M:-30}
data=${SPLATTRACK_DATA:?set SPLATTRACK_DATA to the real sequences}
backends=${1:-cpu lavapipe}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
mkdir -p "$work"

# name|model|sequence|extra flags
cases=(
    "real cube|$data/visp_rbt_cube/model.ply|$data/visp_rbt_cube|"
    "real dragon|$data/visp_rbt_dragon/model.ply|$data/visp_rbt_dragon|"
)
for object in blob plain; do
    for points in 100000 1000000; do
        dir=$work/${object}_$points
        if [ ! -d "$dir" ]; then
            "$bin" synth --object "$object" --points "$points" --frames 100 --out "$dir" >"$dir.synth.log" 2>&1
        fi
        extra=""
        [ "$points" = 1000000 ] && extra="--frames $frames_1m"
        size="${points%000}k"
        [ "$points" = 1000000 ] && size=1M
        cases+=("$object, $size points|$dir/model.ply|$dir|$extra")
    done
done

run() { # backend model sequence out [flags...]
    local backend=$1 model=$2 seq=$3 out=$4
    shift 4
    case $backend in
    cpu) "$bin" track --model "$model" --sequence "$seq" --out "$out" --compute cpu "$@" ;;
    lavapipe) SPLATTRACK_ADAPTER=cpu "$bin" track --model "$model" --sequence "$seq" --out "$out" --compute gpu "$@" ;;
    gpu) "$bin" track --model "$model" --sequence "$seq" --out "$out" --compute gpu "$@" ;;
    *) echo "unknown back end $backend" >&2; exit 2 ;;
    esac
}

# The mean ms a frame of a `track` log.
ms() { sed -nE 's/^tracked .* ([0-9.]+) ms per frame.*/\1/p' "$1"; }
# One stage's mean ms of a `--profile` log (its first line of that name).
stage() { sed -nE "s/^ +$2 +([0-9.]+) ms.*/\1/p" "$1" | head -1; }
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

echo "| case | back end | ms a frame | Harris | IT | KF | contour | check | renders | cues |"
echo "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"
for c in "${cases[@]}"; do
    IFS='|' read -r name model seq extra <<<"$c"
    for b in $backends; do
        tag=$(echo "$name-$b" | tr ' ,' '__')
        times=()
        for i in $(seq "$runs"); do
            # shellcheck disable=SC2086
            run "$b" "$model" "$seq" "$work/$tag.csv" $extra >"$work/$tag.$i.log" 2>&1
            times+=("$(ms "$work/$tag.$i.log")")
        done
        # shellcheck disable=SC2086
        run "$b" "$model" "$seq" "$work/$tag.csv" $extra --profile >"$work/$tag.profile.log" 2>&1
        p=$work/$tag.profile.log
        cues=$(sed -nE 's/^cues: ([a-z,]+).*/\1/p' "$p" | head -1)
        printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$name" "$b" \
            "$(printf '%s\n' "${times[@]}" | median)" \
            "$(stage "$p" 'features \(frame Harris\)')" "$(stage "$p" IT)" "$(stage "$p" KF)" \
            "$(stage "$p" contour)" "$(stage "$p" 'pose check')" \
            "$(sed -nE 's/^ +renders of the model +([0-9.]+).*/\1/p' "$p")" "${cues:-}"
    done
done
