#!/bin/sh
# Installs Debian's chromium for the replay-page test when it is missing (needs root).
set -e
if command -v chromium >/dev/null 2>&1; then exit 0; fi
if [ "$(id -u)" != 0 ]; then
	echo "setup_browser: chromium missing and not root; install Debian's chromium" >&2
	exit 1
fi
apt-get update -q >/dev/null
DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null
