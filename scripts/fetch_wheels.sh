#!/usr/bin/env bash
# Fill ./wheelhouse (git-ignored) with the wheels scripts/device_check.sh installs, for a GPU machine without internet
# (Linux x86_64, CPython ${PYVER:-3.12}); torch is never among them: that machine's own CUDA build stays.
#
#     bash scripts/fetch_wheels.sh            # then carry ./wheelhouse to the GPU machine with the tree
set -euo pipefail
cd "$(dirname "$0")/.."
PYVER=${PYVER:-3.12}
ABI=cp${PYVER/./}
source scripts/device_requirements.sh  # the lists scripts/device_check.sh installs
mkdir -p wheelhouse
python3 -m pip download --disable-pip-version-check --no-deps --only-binary=:all: --dest wheelhouse \
  --python-version "$PYVER" --implementation cp --abi "$ABI" --abi abi3 --abi none \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform any \
  "${NODEPS[@]}" "${PLAIN[@]}"
du -sh wheelhouse
