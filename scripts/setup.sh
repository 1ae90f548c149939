#!/usr/bin/env bash
# Installs the Debian (bookworm) packages the module needs, when they are missing (--fuzz: also those of
# scripts/fuzz.sh).
set -euo pipefail

packages=(
  cmake ninja-build g++ pkg-config
  libinsighttoolkit5-dev  # ITK 5.2: images, meshes, IO
  libcgal-dev             # Delaunay tetrahedralization (exact predicates)
  libeigen3-dev           # sparse least squares of the vertex values
  zlib1g-dev              # crc32 of the .dcv files
  libopenjp2-7-dev        # JPEG 2000 of the residual layer
  libopenjp2-tools        # opj_decompress: the reference decoder's residual layer
  libx265-dev             # HEVC of the video layer (encoding)
  libde265-dev            # HEVC of the video layer (decoding)
  libde265-examples       # dec265: the reference decoder's video layer
  libaom-dev              # AV1 of the video layer (encoding)
  libdav1d-dev            # AV1 of the video layer (decoding)
  dav1d                   # dav1d: the reference decoder's AV1 video layer
  libtbb-dev              # the encoder's threads (oneTBB)
  libcli11-dev            # dcv's arguments, and those of the Slicer modules
  libexpat1-dev           # the Slicer modules read their own module description (XML)
  libxml2-utils           # xmllint: the tests validate the Slicer module descriptions against the schema
  libgtest-dev            # tests
  libdcmtk-dev            # DICOM series out; the tests edit copies of the dev series
  dicom3tools             # dciodvfy: the tests check every DICOM file written
  python3                 # the reference decoder of docs/format.md (dcvFormatSpecificationTest)
  python3-vtk9            # VTK's readers check what dcv mesh writes (dcvMeshTest)
  python3-numpy           # ... and probe it at the voxel centres
)

# scripts/fuzz.sh: libFuzzer (clang's runtime); not needed to build or test the module.
if [ "${1:-}" = "--fuzz" ]; then
  packages+=(clang libclang-rt-14-dev)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "Installing: ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
