"""The CLI's error boundary: every expected failure as ONE line naming the input and what is expected.

Why one place: a person running ncbot should see why a command stopped and what to change, never a stack of
frames from torch or cv2; a traceback is reserved for real bugs (and then asks for a report). `one_line(error)`
returns that line for the failures a user can cause or fix (bad values and files, file-system faults such as a
read-only or full disk, resource limits such as an absurd size) and None for everything else: a bug.
"""
from __future__ import annotations

import errno
import os
import pickle
import re
import sys
import zipfile

MAX_LINE = 400  # characters of a library message kept on the one line

# errno -> what went wrong and what is expected, for file-system faults that carry no message of ours
_OS_REASONS = {
    errno.EROFS: "the file system is read-only; expected a writable folder (choose another --out/-o)",
    errno.ENOSPC: "no space left on the device; free some space or choose another folder",
    errno.EDQUOT: "the disk quota is exceeded; free some space or choose another folder",
    errno.EACCES: "permission denied; expected a path you may read/write",
    errno.EPERM: "operation not permitted; expected a path you may read/write",
    errno.EEXIST: "it already exists; expected a new path or a folder",
    errno.EISDIR: "it is a folder; expected a file",
    errno.ENOTDIR: "a part of the path is a file; expected folders",
    errno.ENOENT: "it does not exist",
    errno.ENAMETOOLONG: "the name is too long",
    errno.EMFILE: "too many open files",
    errno.EIO: "input/output error of the device",
}


# torch's refusal of a pickled object, quoted by loaders: it blames the weights_only default and suggests turning it
# off (the wrong cause and an unsafe fix); ncbot says what the file holds instead
UNSAFE_PICKLE = re.compile(r"(UnpicklingError: )?Weights only load failed\..*?(?=\)?$)", re.S)
SAFE_REASON = "it holds Python objects beyond tensors, which ncbot never loads"


class Terminated(BaseException):
    """Raised in the main thread on SIGTERM so writers clean up their temp files like on Ctrl-C."""


_termination_requested = False
_continuation: str | None = None


def continue_with(command: str | None) -> None:
    """Name the command that continues the work in progress (`ncbot train --resume runs/x`), for the CLI's Ctrl-C
    and SIGTERM line; None once nothing is left to continue."""
    global _continuation
    _continuation = command


def continuation() -> str | None:
    return _continuation


def request_termination() -> None:
    """Note a SIGTERM (the CLI's handler, before it raises `Terminated`), for `raise_if_terminated`."""
    global _termination_requested
    _termination_requested = True


def raise_if_terminated() -> None:
    """Raise `Terminated` again if a SIGTERM came: a handler's exception raised inside a finaliser or a library's
    catch-all is printed or dropped, not propagated, and a long loop must still stop at its next step."""
    if _termination_requested:
        raise Terminated()


def squeeze(text: str) -> str:
    """A message as one line: its first non-empty line, capped (torch and cv2 messages run over many)."""
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    line = lines[0] if lines else ""
    return line if len(line) <= MAX_LINE else line[: MAX_LINE - 3] + "..."


def _os_line(error: OSError) -> str:
    where = error.filename if error.filename is not None else None
    # our own one-sentence errors (FileNotFoundError("config file ... not found ...")) have no errno: keep them
    if error.errno is None and error.args:
        return squeeze(str(error.args[0]))
    reason = _OS_REASONS.get(error.errno) or squeeze(error.strerror or str(error))
    if where is None:  # our own OSError(errno, sentence) keeps its sentence; a bare system one gets the reason
        own = error.strerror and error.errno is not None and error.strerror != os.strerror(error.errno)
        return squeeze(error.strerror) if own else reason
    target = f"{where!s}" + (f" -> {error.filename2!s}" if error.filename2 is not None else "")
    return f"cannot use {target!r}: {reason}"


def _is_allocation_error(error: BaseException) -> bool:
    text = str(error)
    return isinstance(error, RuntimeError) and any(
        marker in text for marker in ("can't allocate memory", "DefaultCPUAllocator", "not enough memory",
                                      "Trying to create tensor with negative dimension", "numel: integer multiplication overflow"))


def one_line(error: BaseException) -> str | None:
    """The one line for an expected failure, or None when `error` is a bug that deserves a traceback."""
    import yaml

    from ncbot.pipelines.extras import extra_line

    missing = extra_line(error)  # an optional extra (pyproject.toml) that is not installed
    if missing is not None:
        return missing

    if isinstance(error, UnicodeDecodeError):  # before ValueError: it is one, but names no file
        return (f"input is not UTF-8 text (byte 0x{error.object[error.start]:02x} at position {error.start}); "
                "expected a text file such as a YAML config")
    if isinstance(error, yaml.YAMLError):
        mark = getattr(error, "problem_mark", None)
        return "input is not valid YAML" + (f" (line {mark.line + 1})" if mark else "") + \
            "; expected a YAML mapping written by hand or by ncbot (no !!python tags)"
    if isinstance(error, OSError):
        return _os_line(error)
    if isinstance(error, MemoryError) or _is_allocation_error(error):
        return ("not enough memory for the requested sizes (" + squeeze(str(error) or "MemoryError")[:120] +
                "); expected smaller batch sizes, widths or image sizes")
    if isinstance(error, OverflowError):
        return f"a number is too large ({squeeze(str(error))}); expected a value within the documented bounds"
    if isinstance(error, (pickle.UnpicklingError, zipfile.BadZipFile, EOFError)):
        return f"a file is not a torch checkpoint ncbot can read safely ({squeeze(str(error))[:120]})"
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and isinstance(error, cv2.error):
        return f"OpenCV could not process the image or path ({squeeze(getattr(error, 'err', '') or str(error))})"
    if type(error).__name__ == "ValidationError" and hasattr(error, "errors"):  # pydantic, outside the config
        first = error.errors(include_url=False)[0]
        where = ".".join(str(part) for part in first["loc"])
        return f"value {where!r}: {squeeze(first['msg'])}" if where else squeeze(first["msg"])
    if isinstance(error, ValueError):  # library code's one sentence (docs/design.md, Errors)
        return squeeze(UNSAFE_PICKLE.sub(SAFE_REASON, str(error))) or type(error).__name__
    return None
