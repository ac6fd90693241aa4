"""The one safe YAML loader for every file ncbot reads by name: configs, ablation grids, a run's config.yaml,
robot scene conditions. It lives at the bottom of the import graph so every package can use it."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


def read_yaml(path: str | Path, what: str, expected: str) -> Any:
    """Every YAML file ncbot reads by name (configs, ablation grids, a run's config.yaml, scene conditions), through one safe loader.

    `yaml.safe_load` never builds Python objects (a ``!!python/...`` tag is an error, not code); every failure
    (missing, a folder, unreadable, not UTF-8 text, not YAML) becomes one sentence naming `what` and the file,
    and what was `expected`.
    """
    path = Path(path)
    label = f"{what} {str(path)!r}"
    if path.is_dir():
        raise IsADirectoryError(f"{label} is a folder; expected {expected}")
    if not path.is_file():
        raise FileNotFoundError(f"{label} not found (expected {expected})")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{label} is not UTF-8 text (byte 0x{error.object[error.start]:02x} at position "
                         f"{error.start}); expected {expected}") from None
    except OSError as error:
        raise ValueError(f"{label} cannot be read ({error.strerror or error}); expected {expected}") from None
    if "\x00" in text:
        raise ValueError(f"{label} is a binary file; expected {expected}")
    try:
        return yaml.safe_load(text)
    except yaml.constructor.ConstructorError as error:
        raise ValueError(f"{label} uses a YAML tag ncbot does not load ({squeeze_yaml(error)}); expected {expected}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ValueError(f"{label} is not valid YAML{where}; expected {expected}") from None
    except RecursionError:
        raise ValueError(f"{label} nests too deeply; expected {expected}") from None


def squeeze_yaml(error: Exception) -> str:
    """The problem of a YAML error without its multi-line context."""
    problem = getattr(error, "problem", None) or str(error)
    return " ".join(str(problem).split())[:120]
