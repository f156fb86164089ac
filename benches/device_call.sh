#!/bin/bash
# One device call with everything GPU-side this crate measures or checks
# (docs/performance.md "NVIDIA H200"): build and pack here, run there.
#
#   bash benches/device_call.sh pack    # here: .dev/ (ignored) holds the stripped
#                                       # binaries, 15 GPU test binaries and the real cube
#                                       # and dragon
#   then one `device` run, carry [".gl", ".dev"], timeout_s 590:
#   BUDGET=545 bash benches/device_call.sh run
#
# `run` unpacks the Vulkan loader (.gl, docs/benchmarks.md "On an H200/H100"),
# runs each item under its own time limit inside BUDGET seconds, in order
# of value: `splattrack info`; the real cube tracked with `--profile`
# (texture and fused, three times each; render-pass splatter; resident
# loop off), peak host RSS of each; synthetic blobs of 1M and 100k points
# tracked with `--profile`, and the cube and the 1M blob without it (no
# timestamp queries); the per-back-end table (benches/backends.sh, its
# `gpu` rows); the features, splat (colour + predictors) and
# tracker benches with the 1M models; then the GPU test binaries on the
# device. Logs and criterion's results come back as $OUT/results.tgz
# (refreshed after every item, so a cut-off run still returns what it
# did) and the summary as $OUT/log.txt. `DRY=1 ADAPTER=cpu` tries the
# script here (15 s an item); `SKIP=regex` leaves out the items whose
# names match (e.g. `SKIP='bench_splat|render|nores'` when those are
# already measured).
set -u
case "${1:-}" in
pack)
    set -e
    rm -rf .dev && mkdir -p .dev/bin
    grep -qx '/.dev/' "$(git rev-parse --git-path info/exclude)" 2>/dev/null ||
        echo /.dev/ >>"$(git rev-parse --git-path info/exclude)"
    sh benches/device.sh build
    cp target/device/* .dev/bin/
    cargo test --release --locked --no-run --message-format=json 2>/dev/null | python3 -c '
import json, shutil, sys
want = {"splat_compute", "splat_window", "splat_depth", "splat_analytic", "splat_reference",
        "splat_memory", "features_resident", "features_ncc", "features_harris", "outline_gpu",
        "verify_gpu", "gpu_context", "keyframes", "contour", "tracker"}
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["profile"]["test"] \
            and m["target"]["name"] in want and "test" in m["target"]["kind"]:
        shutil.copy(m["executable"], ".dev/bin/t_" + m["target"]["name"])
'
    strip .dev/bin/*
    tar cJf .dev/bins.tar.xz -C .dev bin && rm -rf .dev/bin
    mkdir -p .dev/shared/data && cp -r ../shared/data/visp_rbt_cube ../shared/data/visp_rbt_dragon .dev/shared/data/
    chmod -R u+w .dev
    du -sh .dev
    exit 0
    ;;
run) ;;
*)
    echo "usage: bash benches/device_call.sh pack | run" >&2
    exit 2
    ;;
esac
cat > /tmp/rss.py <<'PY'
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:])
print("peak rss of the child: %.1f MB" % (resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024), file=sys.stderr)
sys.exit(r.returncode)
PY
set -u
START=$(date +%s)
BUDGET=${BUDGET:-550}
OUT=${OUT:-/tmp/out}
R=/tmp/r; rm -rf $R; mkdir -p $R $OUT
exec > >(tee -a $OUT/log.txt) 2>&1
left() { echo $((BUDGET - ($(date +%s) - START))); }
snap() { tar czf $OUT/results.tgz -C $R . 2>/dev/null; }
item() { # name limit cmd...
  local name=$1 lim=$2; shift 2
  if [ -n "${SKIP:-}" ] && [[ $name =~ $SKIP ]]; then echo "SKIP $name (SKIP=$SKIP)"; return; fi
  local l=$(( $(left) - 5 )); [ "${DRY:-0}" = 1 ] && lim=15
  [ $lim -gt $l ] && lim=$l
  if [ $lim -lt 8 ]; then echo "SKIP $name (no time left)"; return; fi
  local t0=$(date +%s.%N)
  timeout -k 5 $lim "$@" > $R/$name.log 2>&1; local rc=$?
  printf 'ITEM %-28s rc=%-3s %6.1f s (limit %s)\n' $name $rc $(awk "BEGIN{print $(date +%s.%N) - $t0}") $lim
  [ "${TAILN:-3}" -gt 0 ] && tail -n ${TAILN:-3} $R/$name.log | sed 's/^/    /'
  snap
}

if [ "${DRY:-0}" != 1 ]; then
  for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
export SPLATTRACK_ADAPTER=${ADAPTER:-discrete}
python3 -c "import tarfile; tarfile.open('.dev/bins.tar.xz').extractall('/tmp/dev')"
B=/tmp/dev/bin
[ "$PWD" = /work/main ] || [ -e /work/main ] || { mkdir -p /work; ln -s "$PWD" /work/main; }
[ -e /work/shared ] || ln -s "$PWD/.dev/shared" /work/shared
[ -e ../shared ] || ln -s "$PWD/.dev/shared" ../shared
echo "setup $(( $(date +%s) - START )) s; repo $PWD"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,memory.used,temperature.gpu,utilization.gpu --format=csv 2>&1 | head -3
lscpu | grep -E "Model name|^CPU\(s\)"
# The SM clock and load through the run (an idle GPU clocks down: one-off
# pass timings right after CPU benches are suspect), in results.tgz.
(nvidia-smi --query-gpu=timestamp,clocks.sm,utilization.gpu,power.draw --format=csv -lms 500 \
    >$R/smi.csv 2>/dev/null &)
if ! $B/splattrack info > $R/info.txt 2>&1; then
  cat $R/info.txt
  ls -la /usr/local/nvidia/share/vulkan/icd.d/ /etc/vulkan/icd.d /usr/share/vulkan/icd.d 2>&1
  find / -name '*nvidia_icd*' -not -path '/proc/*' 2>/dev/null | head
  ldconfig -p | grep -i -E "vulkan|nvidia" | head
  unset VK_DRIVER_FILES; $B/splattrack info 2>&1
  for j in $(find / -name '*nvidia_icd*.json' -not -path '/proc/*' 2>/dev/null); do VK_DRIVER_FILES=$j $B/splattrack info 2>&1 && export VK_DRIVER_FILES=$j && break; done
  $B/splattrack info > $R/info.txt 2>&1 || { cat $R/info.txt; snap; echo "NO ADAPTER"; exit 3; }
fi
cat $R/info.txt; snap
C=.dev/shared/data/visp_rbt_cube
# The profile's summary lines (its GPU passes stay in the logs).
summary() { [ -f $R/$1.log ] && grep -E "^tracked|frame source|^  (features \(frame Harris\)|IT|KF|contour|pose check|total|read back from the GPU|waiting for the GPU|GPU work) +[0-9]|^GPU timeline|end to end|peak rss" $R/$1.log | sed 's/^/    /'; }
TAILN=0
for k in 1 2 3; do
  # Without --profile (no timestamp queries), then with it.
  item cube_plain$k 40 python3 /tmp/rss.py $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_plain$k.csv
  summary cube_plain$k
  # The same with wgpu's validation of indirect dispatches (wgpu's
  # default): its cost, alternated.
  item cube_valid$k 40 env WGPU_VALIDATION_INDIRECT_CALL=1 python3 /tmp/rss.py $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_valid$k.csv
  summary cube_valid$k
  item cube_tex$k   40 python3 /tmp/rss.py $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_tex$k.csv --profile
  summary cube_tex$k
  item cube_fused$k 40 python3 /tmp/rss.py $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_fused$k.csv --modalities texture,contour --profile
  summary cube_fused$k
done
item cube_tex_render 30 $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_tex_render.csv --splatter render --profile
summary cube_tex_render
item cube_tex_nores  30 $B/splattrack track --model $C/model.ply --sequence $C --out $R/cube_tex_nores.csv --resident off --profile
summary cube_tex_nores
TAILN=3
item synth1m        60 $B/splattrack synth --object blob --frames 40 --width 640 --height 480 --points 1000000 --out /tmp/blob1m
TAILN=0
item blob1m_plain   50 python3 /tmp/rss.py $B/splattrack track --model /tmp/blob1m/model.ply --sequence /tmp/blob1m --out $R/blob1m_plain.csv
summary blob1m_plain
item blob1m_tex     50 python3 /tmp/rss.py $B/splattrack track --model /tmp/blob1m/model.ply --sequence /tmp/blob1m --out $R/blob1m_tex.csv --profile
summary blob1m_tex
item blob1m_fused   50 python3 /tmp/rss.py $B/splattrack track --model /tmp/blob1m/model.ply --sequence /tmp/blob1m --out $R/blob1m_fused.csv --modalities texture,contour --profile
summary blob1m_fused
# The per-back-end table of docs/performance.md, this machine's GPU row.
TAILN=14
item backends      180 env BIN=$B/splattrack SPLATTRACK_DATA=.dev/shared/data WORK=/tmp/backends bash benches/backends.sh gpu
TAILN=0
TAILN=3
item synth100k      40 $B/splattrack synth --object blob --frames 40 --width 640 --height 480 --points 100000 --out /tmp/blob100k
TAILN=0
item blob100k_tex   40 python3 /tmp/rss.py $B/splattrack track --model /tmp/blob100k/model.ply --sequence /tmp/blob100k --out $R/blob100k_tex.csv --profile
summary blob100k_tex
export CRITERION_HOME=$R/criterion SPLATTRACK_BENCH_1M=1
TAILN=30
item bench_features 130 $B/features --bench
TAILN=3
item bench_splat    130 $B/splat --bench 'color\+predictors|cpu'
grep -sE "gpu timestamps|gpu memory" $R/bench_splat.log | sed 's/^/    /'
item bench_tracker  200 $B/tracker --bench
grep -sE "stages|gpu memory n|gpu memory kf" $R/bench_tracker.log | sed 's/^/    /'
TAILN=4
for t in splat_compute features_resident features_ncc features_harris outline_gpu verify_gpu splat_window splat_depth splat_analytic splat_reference splat_memory gpu_context keyframes contour tracker; do
  item test_$t 60 $B/t_$t --test-threads=4
done
echo "total $(( $(date +%s) - START )) s"
snap
