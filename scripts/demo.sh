#!/usr/bin/env bash
# Builds dcv, makes a 3D Shepp-Logan phantom, compresses it to 0.0625 bits per voxel and decompresses it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
mkdir -p build/demo
build/tools/dcv/dcv phantom build/demo/phantom.nrrd --size 128 --force
echo "Wrote build/demo/phantom.nrrd (128^3, uint8, $(stat -c %s build/demo/phantom.nrrd) bytes as gzip NRRD)"
build/tools/dcv/dcv compress build/demo/phantom.nrrd build/demo/phantom.dcv --bpv 0.0625 --force
echo "Wrote build/demo/phantom.dcv"
build/tools/dcv/dcv decompress build/demo/phantom.dcv build/demo/phantom-decoded.nrrd --force
echo "Wrote build/demo/phantom-decoded.nrrd"
