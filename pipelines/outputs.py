"""Outputs checked before any work starts: a folder that is a file, a path on a read-only disk, a file name
that is a folder or has the wrong suffix, too little free space: one sentence naming the option, at once.

Why: the same faults found after minutes of work leave partial output and an OSError deep in torch or cv2.
Nothing here creates a file or folder (a failed command leaves nothing behind).
"""
from __future__ import annotations

import errno
import os
from pathlib import Path


def nearest_existing(path: Path) -> Path:
    """`path` or its closest existing ancestor (what decides whether `path` can be created)."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_writable_dir(path: str | os.PathLike, option: str) -> Path:
    """One-line error unless `path` is (or can be created as) a folder we may write; creates nothing."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(f"{option} {str(path)!r} is an existing file; expected a folder (new or existing)")
    base = nearest_existing(path)
    if not base.is_dir():
        raise NotADirectoryError(f"{option} {str(path)!r} cannot be created: {str(base)!r} is a file, not a folder")
    if _virtual(base):
        raise PermissionError(f"{option} {str(path)!r} is not writable: {str(base)!r} is on a virtual file system "
                              "(such as /proc or /sys) that holds no files; expected a writable folder")
    if not os.access(base, os.W_OK | os.X_OK):
        reason = "is on a read-only file system" if _read_only(base) else "is not writable by you"
        raise PermissionError(f"{option} {str(path)!r} cannot be written: {str(base)!r} {reason}; "
                              "expected a writable folder")
    return path


def check_writable_file(path: str | os.PathLike, option: str, suffixes: tuple[str, ...] = ()) -> Path:
    """One-line error unless `path` can be written as a file (not a folder, right suffix, writable parent)."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{option} {str(path)!r} is a folder; expected a file name"
                                + (f" ending in {' or '.join(suffixes)}" if suffixes else ""))
    if suffixes and path.suffix.lower() not in suffixes:
        raise ValueError(f"{option} {str(path)!r} must end in {' or '.join(suffixes)}")
    check_writable_dir(path.parent, f"the folder of {option}")
    return path


def _virtual(path: Path) -> bool:
    """A kernel file system (/proc, /sys): no blocks at all, so no file can be written there, even by root."""
    try:
        return os.statvfs(path).f_blocks == 0
    except OSError:
        return False


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def check_free_space(path: str | os.PathLike, needed: int, what: str) -> None:
    """One-line error when the file system of `path` has less than `needed` bytes free (when it can be known)."""
    try:
        stats = os.statvfs(nearest_existing(Path(path)))
    except OSError:
        return
    free = stats.f_bavail * stats.f_frsize
    if stats.f_blocks == 0:  # a virtual file system: not full, not writable (check_writable_dir says so)
        return
    if free < needed:
        raise OSError(errno.ENOSPC, f"{what} needs about {needed / 2**20:.1f} MiB but {str(path)!r} has "
                      f"{free / 2**20:.1f} MiB free; free some space or choose another --out")
