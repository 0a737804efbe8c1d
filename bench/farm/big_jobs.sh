#!/usr/bin/env bash
# bench/farm/big_jobs.sh [BUILD_DIR]: big jobs at scale (issue #25, item 5).
# bench/farm/scale.sh with WORKERS simulated workers connected, then one
# job of FRAMES x BANDS bands (1,000,000 by default) submitted; prints the
# submit time, the time of `locus status` on it and of the job list, and
# the coordinator's peak RSS over SECONDS_SAMPLED while every worker holds
# a lease and the other bands stay queued (locus-farm-scale
# --measure-queued); the jobs are not finished.
#   WORKERS (1000) JOBS (1) FRAMES (10000) BANDS (100) ROWS (1) WIDTH (16)
#   DELAY_MS (60000: a lease outlives the sampling) SECONDS_SAMPLED (10)
set -euo pipefail
SYNCS=0 WORKERS=${WORKERS:-1000} JOBS=${JOBS:-1} FRAMES=${FRAMES:-10000} BANDS=${BANDS:-100} \
  ROWS=${ROWS:-1} WIDTH=${WIDTH:-16} DELAY_MS=${DELAY_MS:-60000} \
  SCALE_FLAGS="--measure-queued ${SECONDS_SAMPLED:-10}" \
  exec bash "$(dirname "$0")/scale.sh" "$@"
