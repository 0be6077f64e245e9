#!/usr/bin/env bash
# Installs the peer tools the benchmarks in bench/ compare setlight with (Debian packages;
# see ../shared/peers/README.md). Not needed to build or test setlight; CI does not run it.
set -euo pipefail
packages=(blender python3-opencv python3-numpy pfstools luminance-hdr hugin-tools enblend
          openimageio-tools time)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    sudo=""; [ "$(id -u)" -ne 0 ] && sudo=sudo
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
