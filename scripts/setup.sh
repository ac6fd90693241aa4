#!/usr/bin/env bash
# One-time, idempotent set-up of a fresh machine of this kind (Debian 12, Python 3.11, CPU only, root).
#   bash scripts/setup.sh        full (the tests, CI): the software Vulkan driver SAPIEN renders with, the TTS engines
#                                the robot speaks with (flite, espeak-ng), headless Chromium for the browser tests,
#                                the CPU build of torch from local disk and ncbot with every extra (`.[all]`)
#   bash scripts/setup.sh base   the main job (train, evaluate): the CPU build of torch and ncbot's base install only
# Both install the tested versions (constraints.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
mode="${1:-full}"
case "$mode" in
  full) extras="[all]" ;;
  base) extras="" ;;
  *) printf '[setup] unknown mode %q; expected full (default) or base\n' "$mode" >&2; exit 2 ;;
esac

log() { printf '[setup] %s\n' "$*"; }

install_lavapipe() {
  # SAPIEN needs Mesa >= 24.3 (lavapipe with VK_KHR_external_semaphore_fd): take it from bookworm-backports.
  if [ -f /usr/share/vulkan/icd.d/lvp_icd.json ] && dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null | grep -Eq '^(2[5-9]|24\.3)'; then
    log "lavapipe already installed"; return
  fi
  if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
    log "not root or no apt-get: install mesa-vulkan-drivers >= 24.3 yourself (see docs/sapien-on-cpu.md)"; return
  fi
  local src=/etc/apt/sources.list.d/debian.sources bp=/etc/apt/sources.list.d/ncbot-backports.sources
  if [ -f "$src" ] && [ ! -f "$bp" ] && grep -q bookworm "$src"; then
    # Same mirror as the machine's first stanza, suite bookworm-backports (no host name is written here).
    awk 'BEGIN{RS="";ORS="\n\n"} NR==1{print}' "$src" | sed -E 's/^Suites:.*/Suites: bookworm-backports/' > "$bp"
  fi
  log "installing mesa-vulkan-drivers from bookworm-backports"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null
}

apt_install() {
  # apt_install WHAT HINT PACKAGE...: install Debian packages as root, or say what to install by hand.
  local what=$1 hint=$2; shift 2
  if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
    log "not root or no apt-get: install $what yourself ($hint)"; return
  fi
  log "installing $what"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

install_tts() {
  # speech/tts.py runs flite (the simulated person's voices) and espeak-ng (the robot's voice) as subprocesses.
  if command -v flite >/dev/null && command -v espeak-ng >/dev/null; then
    log "TTS engines already installed"; return
  fi
  apt_install "the TTS engines flite and espeak-ng" docs/speech.md flite espeak-ng
}

install_chromium() {
  # The browser tests of `ncbot robot serve` drive Debian's headless Chromium through its WebDriver (Selenium).
  if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then
    log "chromium and chromium-driver already installed"; return
  fi
  apt_install "chromium and chromium-driver" docs/browser.md chromium chromium-driver
}

install_python() {
  if ! python -c "import torch, sys; sys.exit(0 if torch.__version__.startswith('2.13.0') else 1)" 2>/dev/null; then
    log "installing torch==2.13.0 (CPU build from local disk)"
    python -m pip install -q torch==2.13.0
  fi
  log "installing ncbot${extras} and its dependencies (tested versions: constraints.txt)"
  python -m pip install -q -c constraints.txt -e ".${extras}"
  # sapien depends on opencv-python (GUI build); both install the cv2 module into the same folder.
  # Keep only the headless build importable: drop the GUI wheel, then reinstall headless over it.
  if python -m pip show -q opencv-python >/dev/null 2>&1; then
    python -m pip uninstall -q -y opencv-python
    python -m pip install -q --force-reinstall --no-deps "$(python -m pip show opencv-python-headless | awk '/^Version:/{print "opencv-python-headless==" $2}')"
  fi
}

if [ "$mode" = full ]; then
  install_lavapipe
  install_tts
  install_chromium
fi
install_python
log "done ($mode)"
