#!/usr/bin/env bash
# Installs every Debian package setlight needs to build, test and benchmark.
# Safe to run again: apt-get skips what is installed. Uses sudo when not root.
set -euo pipefail
packages=(
  build-essential cmake pkg-config git
  libopenexr-dev libimath-dev openexr libdeflate-dev
  libopenimageio-dev openimageio-tools
  libopencv-dev libopencv-contrib-dev
  libgphoto2-dev gphoto2
  libopencolorio-dev
  libraw-dev
  libpng-dev
  libjpeg62-turbo-dev   # core/photo_jpeg.c (the libjpeg OpenImageIO uses)
  libtiff-dev   # core/photo_tiff.c (the libtiff OpenImageIO uses)
  libjansson-dev
  libssl-dev
  python3 python3-jsonschema   # tests/cli/check_jobs.py: the job graph against docs/jobs.schema.json
  chromium-headless-shell   # the tests open the HTML reports in a real browser
  python3-numpy python3-opencv
  clang libclang-rt-14-dev   # the fuzz targets (libFuzzer: -DSETLIGHT_FUZZ=ON, fuzz/README.md)
  slurmctld slurmd slurm-client munge iproute2   # --farm slurm; tests/slurm/cluster.sh (docs/slurm.md)
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
