#!/usr/bin/env bash
# Install everything MCAHRS needs on a fresh Debian machine, then the package itself
# (editable, so the cffi extension is built from the C sources by CMake).
#   Debian: cmake, the Cortex-M4F cross compiler with newlib, QEMU for the emulated target.
#   PyPI:   the package with its test and real-data extras (pyproject.toml).
set -euo pipefail
cd "$(dirname "$0")/.."

debs="cmake gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm"
missing=""
for p in $debs; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
    sudo_cmd=""
    [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
    echo "installing Debian packages:$missing"
    $sudo_cmd apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq $missing >/dev/null
fi

python3 -m pip install -q --disable-pip-version-check -e '.[test,data]'
