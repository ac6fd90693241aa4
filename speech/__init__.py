"""ncbot speech: offline text-to-speech (flite, espeak-ng), background noise, a pocketsphinx recogniser with a
small language model of the example dialogues, and an ASR channel model fitted from real round trips so the
training env can hear "like the recogniser" without running it.

Layer: imports ``envs`` (the example dialogues) only. Audio is always 16 kHz mono int16 (``SAMPLE_RATE``).
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO

SAMPLE_RATE = 16_000


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Write a file through ``write(binary_stream)`` into a temporary file beside ``path``, then rename it over
    ``path``: readers never see a half-written channel model or WAV."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as stream:
            write(stream)
        os.chmod(temporary, 0o644)  # mkstemp makes it owner-only; a model or a WAV is for everyone to read
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path
