#!/usr/bin/env bash
# Installs every Debian package cpgait needs to build, test and serve, then the dashboard's npm
# packages. Idempotent and non-interactive: safe to run on every build.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev libceres-dev libopencv-dev libapriltag-dev
  libcpp-httplib-dev nlohmann-json3-dev libpugixml-dev libsqlite3-dev libpq-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev
  zip  # the ZIP reader's tests read archives made by Info-ZIP
  postgresql  # the scale-out tests start their own server (initdb into a temporary folder)
  chromium  # the dashboard's browser tests (driven by playwright-core from npm)
)
# Node.js and npm for the dashboard, from Debian unless a newer one is already on the machine.
command -v npm >/dev/null 2>&1 || PACKAGES+=(nodejs npm)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The dashboard's packages come from its committed lock file (nothing fetched at run time).
here="$(cd "$(dirname "$0")" && pwd)"
if [ -f "$here/web/package-lock.json" ] && command -v npm >/dev/null 2>&1; then
  (cd "$here/web" && npm ci --no-audit --no-fund --loglevel=error)
fi
