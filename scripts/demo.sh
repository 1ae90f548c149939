#!/usr/bin/env bash
# Builds dcv, makes a 3D Shepp-Logan phantom and approximates it with 20,000 points.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
mkdir -p build/demo
build/cli/dcv phantom build/demo/phantom.nrrd --size 128 --force
echo "Wrote build/demo/phantom.nrrd (128^3, uint8)"
build/cli/dcv approximate build/demo/phantom.nrrd build/demo/phantom-approximation.nrrd --points 20000 --force
echo "Wrote build/demo/phantom-approximation.nrrd"
