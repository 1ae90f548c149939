#!/bin/sh
# Thin wrapper: rate-distortion comparison of dcv vs OpenJPEG, x265 and aomenc (see scripts/rd_benchmark.py).
# Example: scripts/rd_benchmark.sh --volumes head-mr.nrrd flair-mr.nrrd --bpv 0.03125
exec /usr/bin/python3 "$(dirname "$0")/rd_benchmark.py" "$@"
