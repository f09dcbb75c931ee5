#!/usr/bin/env bash
# Install Debian's Chromium (headless browser for tests/preview/test_preview_browser.py).
# Idempotent: does nothing when a chromium binary is already on PATH.
# Needs root (CI runs as root); exits non-zero with a message when the install fails.
set -u

find_chromium() {
    command -v chromium || command -v chromium-browser || command -v google-chrome || true
}

existing="$(find_chromium)"
if [ -n "$existing" ]; then
    echo "install_browser: chromium already installed: $existing ($("$existing" --version 2>/dev/null || echo 'version unknown'))"
    exit 0
fi

if [ "$(id -u)" -ne 0 ]; then
    echo "install_browser: chromium is missing and this script must run as root to install it" >&2
    exit 2
fi

export DEBIAN_FRONTEND=noninteractive
echo "install_browser: installing chromium with apt-get"
if ! apt-get update -qq; then
    echo "install_browser: 'apt-get update' failed" >&2
    exit 3
fi
# fonts-dejavu-core gives Chromium a font for the HTML overlay text.
if ! apt-get install -y -qq --no-install-recommends chromium fonts-dejavu-core >/dev/null; then
    echo "install_browser: 'apt-get install chromium' failed" >&2
    exit 4
fi

installed="$(find_chromium)"
if [ -z "$installed" ]; then
    echo "install_browser: apt-get succeeded but no chromium binary is on PATH" >&2
    exit 5
fi
echo "install_browser: installed $installed ($("$installed" --version 2>/dev/null || echo 'version unknown'))"
