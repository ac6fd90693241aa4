"""Optional extras: a command whose extra is not installed stops with ONE line naming the pip command to run.

Why: the base install (`pip install ncbot`) trains, evaluates, ablates and reads logs; the simulated robot
(sapien), speech recognition (pocketsphinx; pyroomacoustics and webrtcvad for Pepper's microphone array), the browser
server (fastapi, uvicorn, websockets), the rerun export, OpenSpiel's bots and the Ray and Slurm backends are extras
(pyproject.toml). `require(extra, module)` checks at a command's
entry that the module is installed -- without importing it, so nothing heavy starts and no import-time side
effect runs early (sapien reads the Vulkan set-up when it is imported) -- and raises `MissingExtra` otherwise;
the CLI's error boundary (pipelines/errors.py) prints its message as one line and exits 2. `extra_line` is the
same line for a ModuleNotFoundError of an optional module raised deeper, where no entry point checked first.
Light: no ncbot or third-party imports.
"""
from __future__ import annotations

import importlib.util

#: top-level module -> (extra that installs it, its distribution name on PyPI)
OPTIONAL_MODULES = {
    "sapien": ("robot", "sapien"),
    "pocketsphinx": ("speech", "pocketsphinx"),
    "pyroomacoustics": ("speech", "pyroomacoustics"),
    "webrtcvad": ("speech", "webrtcvad-wheels"),
    "fastapi": ("serve", "fastapi"),
    "uvicorn": ("serve", "uvicorn"),
    "websockets": ("serve", "websockets"),
    "httpx": ("serve", "httpx"),
    "rerun": ("rerun", "rerun-sdk"),
    "pyspiel": ("openspiel", "open_spiel"),
    "open_spiel": ("openspiel", "open_spiel"),
    "tree": ("openspiel", "dm-tree"),
    "ray": ("ray", "ray"),
    "submitit": ("slurm", "submitit"),
    "selenium": ("test", "selenium"),
}


class MissingExtra(ImportError):
    """An optional extra a command needs is not installed; the message is the one line to show."""


def missing_line(extra: str, module: str, what: str | None = None) -> str:
    package = OPTIONAL_MODULES.get(module, (extra, module))[1]
    return (f"{what or 'this command'} needs the optional extra [{extra}] ({package} is not installed); "
            f"install it with: pip install 'ncbot[{extra}]'")


def installed(module: str) -> bool:
    """Whether the top-level `module` can be imported (found on the path; not imported here)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a broken or half-removed install counts as missing
        return False


def require(extra: str, *modules: str, what: str | None = None) -> None:
    """Raise MissingExtra (one line: which extra, the pip command) unless every top-level module is installed."""
    for module in modules:
        if not installed(module):
            raise MissingExtra(missing_line(extra, module, what))


def extra_line(error: BaseException) -> str | None:
    """The one line for a ModuleNotFoundError of an optional module that is not installed, else None."""
    if isinstance(error, MissingExtra):
        return str(error)
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    top = error.name.split(".")[0]
    if top not in OPTIONAL_MODULES or installed(top):
        return None  # a base dependency missing, or a module missing inside an installed package: a real fault
    return missing_line(OPTIONAL_MODULES[top][0], top)
