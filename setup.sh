#!/usr/bin/env bash
# Installs everything on a fresh Debian 12: the system libraries gmsh's wheel and vtk's off-screen
# rendering need, then a virtual environment .venv with the toolkit and its test extra.
set -euo pipefail
cd "$(dirname "$0")"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends \
    libglu1-mesa libgl1 libxcursor1 libxft2 libxinerama1 libgomp1 libegl1 python3-venv >/dev/null
[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[test]"
