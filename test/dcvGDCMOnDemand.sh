#!/usr/bin/env bash
# The programs load GDCM (its library fills its dictionaries when loaded: 26 ms) only when they meet
# DICOM: not for NRRD in and out, nor for a DICOM series written (DCMTK); then for a DICOM series read.
# Usage: dcvGDCMOnDemand.sh DCV WORKDIR DATADIR (../shared/data: the CT series, skipped when absent)
set -euo pipefail
dcv=$1
work=$2
ct=$3/dicom-ct-brain-5mm
rm -rf "$work" && mkdir -p "$work"
# The dynamic loader names every library it loads (on stderr); the command itself must succeed.
loads_gdcm() {
  local log
  log=$(LD_DEBUG=files "$@" 2>&1 >/dev/null) || { echo "failed: $*"; exit 1; }
  [[ $log == *file=libgdcm* ]]
}

loads_gdcm "$dcv" --version && { echo "dcv --version loaded GDCM"; exit 1; }
loads_gdcm "$dcv" phantom "$work/p.nrrd" --size 24 -f && { echo "dcv phantom loaded GDCM"; exit 1; }
loads_gdcm "$dcv" compress "$work/p.nrrd" "$work/p.dcv" --points 40 -f -q && { echo "compressing NRRD loaded GDCM"; exit 1; }
loads_gdcm "$dcv" decompress "$work/p.dcv" "$work/q.nrrd" -f -q && { echo "decompressing to NRRD loaded GDCM"; exit 1; }
loads_gdcm "$dcv" decompress "$work/p.dcv" "$work/series" --dicom -f -q && { echo "writing DICOM loaded GDCM"; exit 1; }
test -f "$work/q.nrrd" && test -d "$work/series"
# A .dcm name (GDCM's ImageIO, through ITK's factories) needs it, and the same check sees it.
loads_gdcm "$dcv" decompress "$work/p.dcv" "$work/q.dcm" -f -q || { echo "writing .dcm did not load GDCM"; exit 1; }
test -s "$work/q.dcm"
# So does reading a DICOM series.
if [ -d "$ct" ]; then
  loads_gdcm "$dcv" compress "$ct" "$work/ct.dcv" --points 40 -f -q || { echo "reading DICOM did not load GDCM"; exit 1; }
  test -s "$work/ct.dcv"
else
  echo "skipped the series read: no $ct"
fi
echo "GDCM loaded only for DICOM"
