#!/usr/bin/env bash
# Make a headless Chromium available for the report test (tests/test_report_browser.py).
#
# Prints the browser's path. Uses one already on PATH (chromium, chromium-browser, google-chrome);
# otherwise installs Debian's chromium with apt-get (needs root and the package registry).
# Exits nonzero, with the reason on stderr, when no browser can be had.
set -euo pipefail

find_browser() {
    for b in chromium chromium-browser google-chrome; do
        if command -v "$b" >/dev/null; then command -v "$b"; return 0; fi
    done
    return 1
}

if find_browser; then exit 0; fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
    echo "browser: no chromium on PATH, and installing one needs root and apt-get" >&2; exit 1
fi
echo "browser: installing chromium (apt-get)" >&2
if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null 2>&1; then
    DEBIAN_FRONTEND=noninteractive apt-get update -q >/dev/null 2>&1 || true
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null
fi
find_browser
