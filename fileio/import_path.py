"""A class a user names by import path, `package.module:Name` or `path/to/file.py:Name`, loaded with one-line errors.

Why here: the bottom package, so every part that accepts a user's class by path (objectives, games) loads it the same
way (as `gymnasium.make("pkg.mod:Env")` does). Nothing is imported unless the user named it on the command line or
in their own config.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from hashlib import sha1
from pathlib import Path
from typing import Any


def is_import_path(name: str) -> bool:
    """`module:Name` or `file.py:Name` (a registered short name has no colon)."""
    return ":" in name


def split_import_path(spec: str, what: str) -> tuple[str, str]:
    """(module or .py file, attribute) of `spec`; ValueError naming `what` when it is neither form."""
    where, _, name = spec.rpartition(":")
    if not where or not name.isidentifier():
        raise ValueError(f"{what} {spec!r}: an import path is MODULE:CLASS or PATH.py:CLASS")
    if not where.endswith(".py") and not all(part.isidentifier() for part in where.split(".")):
        raise ValueError(f"{what} {spec!r}: {where!r} is neither a module name nor a .py file")
    return where, name


def absolute_import_path(spec: str, what: str) -> str:
    """`spec` with a .py file's absolute path, so a config written into a run folder names the same class from
    anywhere; module paths are kept as they are."""
    where, name = split_import_path(spec, what)
    return f"{Path(where).expanduser().resolve()}:{name}" if where.endswith(".py") else spec


def import_object(spec: str, what: str) -> Any:
    """The attribute `spec` names, its module imported now (a file: under a private module name, registered in
    `sys.modules` so dataclasses and pickling find it). ValueError with one line when the module or file does not
    import or lacks the name."""
    where, name = split_import_path(spec, what)
    try:
        if where.endswith(".py"):
            path = Path(where).expanduser()
            if not path.is_file():
                raise ValueError(f"{what} file {where} not found (expected a Python file defining {name})")
            module_name = f"ncbot_user_{path.stem}_{sha1(str(path.resolve()).encode()).hexdigest()[:8]}"
            module = sys.modules.get(module_name)
            if module is None:
                loader_spec = importlib.util.spec_from_file_location(module_name, path)
                module = importlib.util.module_from_spec(loader_spec)
                sys.modules[module_name] = module
                try:
                    loader_spec.loader.exec_module(module)
                except BaseException:
                    del sys.modules[module_name]
                    raise
        else:
            module = importlib.import_module(where)
    except ValueError:
        raise
    except Exception as error:  # noqa: BLE001 - a user's module may raise anything while it imports
        detail = str(error).splitlines()[0] if str(error) else ""
        raise ValueError(f"{what} {spec} does not import: {type(error).__name__}: {detail}") from None
    if not hasattr(module, name):
        raise ValueError(f"{what} {spec}: {where} defines no {name!r}")
    return getattr(module, name)
