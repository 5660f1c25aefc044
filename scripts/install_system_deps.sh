#!/usr/bin/env bash
# System packages the tests use besides Python's: Chromium and its WebDriver (Debian's chromium and
# chromium-driver), in which tests/report/test_report_html.py opens the HTML report. Installed with apt-get
# when missing and possible (as root, or with password-less sudo); otherwise a note on stderr, and
# the browser test skips saying why. This script never fails the install.
set -u
if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "note: no apt-get: install Chromium and its WebDriver yourself for the browser test (it skips without)" >&2
    exit 0
fi
if [ "$(id -u)" = 0 ]; then
    run=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    run="sudo -n"
else
    echo "note: not root: 'apt-get install chromium chromium-driver' for the browser test (it skips without)" >&2
    exit 0
fi
if ! { $run apt-get update -qq && DEBIAN_FRONTEND=noninteractive $run apt-get install -y -qq \
        --no-install-recommends chromium chromium-driver; } >/dev/null; then
    echo "note: apt-get could not install chromium chromium-driver: the browser test will skip" >&2
fi
exit 0
