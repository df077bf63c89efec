#!/usr/bin/env bash
# Install (or reuse) the headless browser the report-rendering tests use, Debian's Chromium at a
# pinned version, and print its path; print nothing (and say why on stderr) when it cannot be
# installed, so those tests skip with that reason. Idempotent: an installed chromium is reused.
set -uo pipefail
pin="148.0.7778.167-1~deb12u1"
if command -v chromium >/dev/null 2>&1; then
    command -v chromium
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "== browser: no apt-get here; the report rendering tests will skip" >&2
    exit 0
fi
sudo=""
if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then sudo="sudo -n"; else
        echo "== browser: not root and no sudo; cannot install chromium; the report rendering tests will skip" >&2
        exit 0
    fi
fi
echo "== browser: installing chromium=$pin (apt-get)" >&2
export DEBIAN_FRONTEND=noninteractive
if ! $sudo apt-get install -y --no-install-recommends "chromium=$pin" >&2; then
    $sudo apt-get update >&2 || true
    if ! $sudo apt-get install -y --no-install-recommends "chromium=$pin" >&2; then
        echo "== browser: chromium=$pin could not be installed; the report rendering tests will skip" >&2
        exit 0
    fi
fi
command -v chromium
