#!/usr/bin/env bash
# Fetches the public ViSP data set (lagadic/visp-images) at a fixed commit
# and converts its rbt/ recording into the two real sequences the real-data
# tests read (visp_rbt_cube, visp_rbt_dragon; docs/testing.md).
#
#   scripts/get_real_data.sh [OUT_DIR]
#
# OUT_DIR defaults to splattrack-data beside the checkout (the data is GPL
# and stays out of the repository). Needs git, python3 (with venv) and a
# network; the conversion installs numpy, scipy, pillow and trimesh into
# OUT_DIR/.venv and takes about 40 minutes on 2 cores (GT=apriltag: about
# 3 minutes, with the coarser board-only ground truth). Then:
#
#   SPLATTRACK_DATA=OUT_DIR cargo test --release
set -euo pipefail

COMMIT=ca09c52fe0ff9bb0ddd0e5e24c6a635ce0fa8b43
REPO=https://github.com/lagadic/visp-images.git
here=$(cd "$(dirname "$0")" && pwd)
out=$(realpath -m "${1:-$here/../../splattrack-data}")
git_dir=$out/.visp-images.git
venv=$out/.venv

mkdir -p "$out"
if ! git --git-dir "$git_dir" cat-file -e "$COMMIT^{commit}" 2>/dev/null; then
    echo "get_real_data: fetching visp-images at $COMMIT"
    [ -d "$git_dir" ] || git init -q --bare "$git_dir"
    git --git-dir "$git_dir" fetch --depth 1 "$REPO" "$COMMIT"
fi
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q numpy scipy pillow trimesh
echo "get_real_data: converting into $out"
"$venv/bin/python" "$here/convert_visp.py" "$git_dir" --out "$out" --commit "$COMMIT" \
    --gt "${GT:-refined}" --jobs "${JOBS:-$(nproc)}"
echo "get_real_data: done; run the real-data tests with"
echo "  SPLATTRACK_DATA=$out cargo test --release"
