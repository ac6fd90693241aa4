"""The robot's voice: every utterance is kept as text; espeak-ng speaks it into a WAV file when installed.

Audio is never required (CI machines have no sound): without espeak-ng, or with audio off, `say` only
records the text, which the game loop logs on the `/dialogue` channel.
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


class Speaker:
    """Says template utterances; `audio_dir` set and espeak-ng found -> one WAV per utterance."""

    def __init__(self, audio_dir: str | Path | None = None, voice: str = "en") -> None:
        self.binary = shutil.which("espeak-ng") or shutil.which("espeak")
        self.audio_dir = Path(audio_dir) if audio_dir is not None and self.binary else None
        if self.audio_dir is not None:
            self.audio_dir.mkdir(parents=True, exist_ok=True)
        self.voice = voice
        self.said: list[str] = []

    @property
    def has_audio(self) -> bool:
        return self.audio_dir is not None

    def say(self, text: str) -> Path | None:
        """Record `text`; with audio on, synthesise it to `utterance-NNNN.wav` and return that path."""
        self.said.append(text)
        if self.audio_dir is None or not text:
            return None
        path = self.audio_dir / f"utterance-{len(self.said) - 1:04d}.wav"
        subprocess.run([self.binary, "-v", self.voice, "-w", str(path), text], check=False,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=30)
        return path if path.exists() else None
