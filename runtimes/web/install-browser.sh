#!/usr/bin/env bash
# Headless Chromium for the browser runtime's tests (WebGPU through SwiftShader): Debian's package.
# Does nothing when a Chromium is already there (SEGADEFORM_CHROMIUM or /usr/bin/chromium).
set -euo pipefail
if [ -x "${SEGADEFORM_CHROMIUM:-/usr/bin/chromium}" ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q chromium
