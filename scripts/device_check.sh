#!/usr/bin/env bash
# train.device on a real GPU: on a fresh machine with Python 3.12 and a CUDA build of torch already installed, put
# in what ncbot needs WITHOUT replacing that torch, run the CUDA-marked tests, then the CPU-vs-GPU benchmark.
#
#     bash scripts/device_check.sh            # logs to $OUT if set (device_check.log, pytest, bench JSON), else /tmp
#
# Packages: from ./wheelhouse when it is there (scripts/fetch_wheels.sh fills it on a machine with internet, for
# a GPU machine that has none), else from PyPI. torchrl/tensordict go in with --no-deps (they would pull a torch);
# everything else is pure Python or has its own wheels, none of them depends on torch. ncbot itself: an editable
# install without dependencies, and PYTHONPATH=this tree in any case.
# Budget: under 8 minutes on a 16-core H100/H200 machine; each step has its own timeout so a hang cannot eat it.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
LOGDIR=${OUT:-/tmp/ncbot-device-check}
mkdir -p "$LOGDIR"
exec > >(tee -a "$LOGDIR/device_check.log") 2>&1
PY=${PYTHON:-python3}
START=$SECONDS
step() { printf '\n[device_check %4ss] %s\n' "$((SECONDS - START))" "$*"; }
FAILED=()

source scripts/device_requirements.sh  # NODEPS (torchrl & co, --no-deps) and PLAIN (the rest)

step "machine"
set -x
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
nproc
$PY --version
timeout 60 $PY -c "import torch; print('torch', torch.__version__, 'cuda', torch.version.cuda, 'available', torch.cuda.is_available(), torch.cuda.device_count())"
{ set +x; } 2>/dev/null
TORCH_BEFORE=$(timeout 60 $PY -c "import torch; print(torch.__version__)" 2>/dev/null || echo none)
if [ "$TORCH_BEFORE" = none ]; then
  echo "device_check: no torch on this machine: install a CUDA build of torch first (this script never installs one)"
  exit 2
fi

step "install what is missing (never torch)"
PIP=($PY -m pip install --disable-pip-version-check --no-input --progress-bar off --timeout 20 --retries 1)
if [ -d wheelhouse ] && ls wheelhouse/*.whl >/dev/null 2>&1; then
  PIP+=(--no-index --find-links wheelhouse)
  echo "packages from ./wheelhouse ($(ls wheelhouse/*.whl | wc -l) wheels)"
fi
set -x
timeout 180 "${PIP[@]}" --no-deps "${NODEPS[@]}" || FAILED+=("pip install ${NODEPS[*]}")
timeout 180 "${PIP[@]}" --no-deps "${PLAIN[@]}" || FAILED+=("pip install of the other dependencies")
timeout 120 $PY -m pip install --disable-pip-version-check --no-input --no-deps --no-build-isolation -e . \
  || echo "editable install failed: running from PYTHONPATH=$ROOT instead"
{ set +x; } 2>/dev/null
export PYTHONPATH=$ROOT${PYTHONPATH:+:$PYTHONPATH}
TORCH_AFTER=$(timeout 60 $PY -c "import torch; print(torch.__version__)" 2>/dev/null || echo none)
echo "torch before: $TORCH_BEFORE, after: $TORCH_AFTER"
if [ "$TORCH_BEFORE" != "$TORCH_AFTER" ]; then
  FAILED+=("torch changed from $TORCH_BEFORE to $TORCH_AFTER")
fi
set -x
timeout 120 $PY -c "import torchrl, tensordict, pydantic, gymnasium, matplotlib, yaml, ncbot.pipelines.train.run; print('imports ok: torchrl', torchrl.__version__, 'tensordict', tensordict.__version__)" \
  || FAILED+=("imports")
{ set +x; } 2>/dev/null

step "CUDA-marked tests"
set -x
timeout 240 $PY -m pytest -m cuda -q -p no:cacheprovider -o addopts="" -ra --junitxml="$LOGDIR/pytest_cuda.xml" \
  tests/train/test_device.py || FAILED+=("pytest -m cuda (rc $?)")
{ set +x; } 2>/dev/null

step "CPU vs GPU benchmark (--quick)"
LEFT=$((460 - (SECONDS - START)))
[ "$LEFT" -lt 60 ] && LEFT=60
set -x
timeout "$LEFT" $PY bench/device_speed.py --quick --json "$LOGDIR/device_speed.json" || FAILED+=("bench/device_speed.py --quick (rc $?)")
{ set +x; } 2>/dev/null

step "done"
if [ ${#FAILED[@]} -gt 0 ]; then
  printf 'device_check: FAILED: %s\n' "${FAILED[@]}"
  exit 1
fi
echo "device_check: all passed; logs in $LOGDIR"
