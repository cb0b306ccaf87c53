#!/usr/bin/env bash
# Renders a timelapse, one frame per array task.
#
#   SCENE_ARGS="--lat 42.4434 --lon -76.4816 --width 1024 --height 512 --spp 32" \
#   TIME_START=2013-05-27T04:00:00-04:00 TIME_END=2013-05-27T22:00:00-04:00 \
#   FRAMES=217 OUT_DIR=/shared/day ./submit-timelapse.sh
#
# Environment: SKYRENDER [skyrender], SCENE_ARGS, TIME_START, TIME_END,
# FRAMES (required), OUT_DIR [./skyrender-frames], WAIT, SBATCH_ARGS.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${SCENE_ARGS:?}" "${TIME_START:?}" "${TIME_END:?}" "${FRAMES:?}"
export SKYRENDER=${SKYRENDER:-skyrender} SCENE_ARGS TIME_START TIME_END FRAMES
export OUT_DIR=${OUT_DIR:-$PWD/skyrender-frames}
mkdir -p "$OUT_DIR"
wait_flag=()
if [ -n "${WAIT:-}" ]; then wait_flag=(--wait); fi
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of flags
job=$(sbatch --parsable ${SBATCH_ARGS:-} --export=ALL --array="1-${FRAMES}" \
  --output="$OUT_DIR/frame-%A_%a.log" "${wait_flag[@]}" "$here/timelapse.sbatch")
echo "frames: job ${job} (${FRAMES} tasks) -> ${OUT_DIR}/sky_####.exr"
