#!/usr/bin/env bash
# Renders one image as TILES array tasks and merges them in a dependent job.
#
#   SCENE_ARGS="--preset sunset --width 4096 --height 2048 --spp 64" \
#   TILES=16 OUT_DIR=/shared/sky ./submit-tiles.sh
#
# Environment: SKYRENDER [skyrender on the PATH], SCENE_ARGS (required),
# TILES [4], OUT_DIR [./skyrender-tiles], OUTPUT [sky.exr], WAIT (set: wait
# for the merge and exit with its status), SBATCH_ARGS (extra sbatch flags,
# e.g. a partition). OUT_DIR must be on a file system every node sees.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${SCENE_ARGS:?set SCENE_ARGS to the scene flags, e.g. --preset sunset --spp 64}"
export SKYRENDER=${SKYRENDER:-skyrender}
export TILES=${TILES:-4}
export OUT_DIR=${OUT_DIR:-$PWD/skyrender-tiles}
export OUTPUT=${OUTPUT:-sky.exr}
export SCENE_ARGS
mkdir -p "$OUT_DIR"
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of flags
array=$(sbatch --parsable ${SBATCH_ARGS:-} --export=ALL --array="0-$((TILES - 1))" \
  --output="$OUT_DIR/tile-%A_%a.log" "$here/tiles.sbatch")
echo "tiles: job ${array} (${TILES} tasks)"
wait_flag=()
if [ -n "${WAIT:-}" ]; then wait_flag=(--wait); fi
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --export=ALL --dependency="afterok:${array}" \
  --kill-on-invalid-dep=yes --output="$OUT_DIR/merge-%j.log" "${wait_flag[@]}" "$here/merge.sbatch")
echo "merge: job ${merge} -> ${OUT_DIR}/${OUTPUT}"
