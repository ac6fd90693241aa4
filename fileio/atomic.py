"""Atomic file writes: a temp file in the target's folder, flushed and fsynced, renamed over the target.

Why each step: the temp file lives in the same folder so the rename stays on one file system (atomic on POSIX:
a reader sees the old file or the new one, never half of either); the fsync before the rename keeps a power loss
from leaving the new name on empty data; the fsync of the folder makes the rename itself durable. The temp file
is created with mode 0666 through the kernel, so the usual umask gives the usual 0644 (``tempfile.mkstemp``
would give 0600), and it is removed when writing fails. A process killed mid-write can leave a hidden
``.NAME.XXXXXXXX.tmp`` file (``TEMP_GLOB``) but never a partial file under the real name.
"""
from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

TEMP_GLOB = ".*.tmp"  # what a killed writer may leave behind: .NAME.XXXXXXXX.tmp beside NAME


def _new_temp_file(path: Path) -> Path:
    """Create an empty, not yet existing temp file beside `path`, with the umask's permissions."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        temp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            os.close(os.open(temp, flags, 0o666))
        except FileExistsError:
            continue
        return temp
    raise FileExistsError(f"could not create a temp file beside {path} (100 names taken)")


def _fsync_file(path: Path) -> None:
    handle = os.open(path, os.O_RDONLY)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


def fsync_folder(folder: str | os.PathLike) -> None:
    """Make a rename or a new file in `folder` durable; a no-op where folders cannot be fsynced."""
    try:
        handle = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(handle)
    except OSError:  # some file systems (and all of Windows) refuse to fsync a folder
        pass
    finally:
        os.close(handle)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temp path for a writer that needs a file name (``torch.save``, ``savefig``, rerun's ``save``);
    when the block ends without error the file is fsynced and renamed to `path`, otherwise removed.

    The temp name ends in ``.tmp``: writers that guess the format from the suffix must be told it
    (``savefig(temp, format="png")``).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = _new_temp_file(path)
    try:
        yield temp
        _fsync_file(temp)
        os.replace(temp, path)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise
    fsync_folder(path.parent)


def atomic_write_bytes(data: bytes, path: str | os.PathLike) -> Path:
    """Write `data` to `path` atomically; returns the path."""
    with atomic_path(path) as temp, open(temp, "wb") as stream:
        stream.write(data)
    return Path(path)


def atomic_write_text(text: str, path: str | os.PathLike, encoding: str = "utf-8") -> Path:
    """Write `text` to `path` atomically; returns the path."""
    return atomic_write_bytes(text.encode(encoding), path)


def move_aside(path: str | os.PathLike, aside: str | os.PathLike) -> Path:
    """Rename `path` to `aside` in one step and make the rename durable; returns `aside`.

    Why here: a file moved out of the way (a stale lock) must never exist under both names or neither
    after a crash, which is the same rename-and-fsync an atomic write ends with.
    """
    aside = Path(aside)
    os.replace(path, aside)
    fsync_folder(aside.parent)
    return aside
