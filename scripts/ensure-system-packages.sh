#!/usr/bin/env bash
# Make sure the Debian packages dermis needs are installed: installs them when running as root
# (apt-get), otherwise prints the exact command to run and fails.
# Usage: scripts/ensure-system-packages.sh PKG...
set -euo pipefail
missing=()
for p in "$@"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done
[ ${#missing[@]} -eq 0 ] && exit 0
if ! command -v apt-get >/dev/null 2>&1; then
    echo "dermis: missing system packages: ${missing[*]} (no apt-get here: install the equivalent headless EGL/OpenGL packages)" >&2
    exit 1
fi
if [ "$(id -u)" -eq 0 ]; then
    echo "dermis: installing system packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
    echo "dermis: missing system packages: ${missing[*]}" >&2
    echo "dermis: run: sudo apt-get install -y ${missing[*]}" >&2
    exit 1
fi
