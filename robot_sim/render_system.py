"""A warm SAPIEN render device per process, a fresh render world per scene, and a clear error when no Vulkan
device exists.

The first frame of a process costs seconds (shader start-up) and again whenever every render system has been
freed, so one `RenderSystem` is kept alive here for the whole process. Each scene still gets a render system of
its own (`new_render_system`, a few ms once the device is warm): a `RenderSystem` is a render world, and scenes
built on a shared one would add their lights and bodies to each other's pictures.
"""
from __future__ import annotations

import os

LAVAPIPE_ICD = "/usr/share/vulkan/icd.d/lvp_icd.json"
SETUP_RECIPE = ("no Vulkan rendering device found: SAPIEN needs lavapipe (Mesa >= 24.3) on a CPU-only machine; "
                "run `bash scripts/setup.sh` as root (installs mesa-vulkan-drivers from bookworm-backports), "
                "see docs/robot.md")

_RENDER_SYSTEM = None


class SimulatorUnavailable(RuntimeError):
    """SAPIEN cannot render here; the message carries the set-up recipe."""


def get_render_system():
    """The process-wide `sapien.render.RenderSystem`, created on first use (lavapipe when present)."""
    global _RENDER_SYSTEM
    if _RENDER_SYSTEM is not None:
        return _RENDER_SYSTEM
    if "VK_ICD_FILENAMES" not in os.environ and os.path.exists(LAVAPIPE_ICD):
        # Prefer a real GPU driver if one is installed; otherwise point the loader straight at lavapipe.
        if not any(os.path.exists(p) for p in ("/usr/share/vulkan/icd.d/nvidia_icd.json",
                                                 "/etc/vulkan/icd.d/nvidia_icd.json")):
            os.environ["VK_ICD_FILENAMES"] = LAVAPIPE_ICD
    try:
        import sapien
    except ImportError as error:  # pragma: no cover - sapien is a declared dependency
        raise SimulatorUnavailable(f"sapien is not installed ({error}); install the robot extra: "
                                   "pip install 'ncbot[robot]' (or run `bash scripts/setup.sh`)") from error
    sapien.render.set_log_level("off")
    try:
        _RENDER_SYSTEM = sapien.render.RenderSystem()
    except RuntimeError as error:
        raise SimulatorUnavailable(f"{SETUP_RECIPE} ({error})") from error
    sapien.render.set_picture_format("Color", "r8g8b8a8unorm")
    return _RENDER_SYSTEM


def new_render_system():
    """A fresh render world for one scene, created on the process's warm device."""
    import sapien

    get_render_system()
    return sapien.render.RenderSystem()
