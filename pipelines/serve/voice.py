"""The robot's voice in the browser: each utterance as a WAV (speech.tts, espeak-ng) served to the session's tabs.

Why a worker thread: synthesis is a subprocess (tens of ms of CPU); the game thread only queues the text, so
neither the robot's next action nor (in serial mode) the other sessions' robots wait for it. Without a TTS
engine the page shows the text alone.
"""
from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from pathlib import Path


class Voice:
    """Synthesises queued utterances in order into `folder`/utterance-NNNN.wav; `on_ready(url, seq)` per WAV."""

    def __init__(self, folder: Path, url_prefix: str, on_ready: Callable[[str, int], None]) -> None:
        self.folder, self.url_prefix, self.on_ready = folder, url_prefix, on_ready
        self.available = True
        self._count = 0
        self._jobs: queue.Queue[tuple[str, int] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._work, name=f"voice-{folder.name}", daemon=True)
        self._thread.start()

    def say(self, text: str, seq: int) -> None:
        if self.available and text:
            self._jobs.put((text, seq))

    def close(self, timeout: float = 10.0) -> None:
        self._jobs.put(None)
        self._thread.join(timeout)

    def _work(self) -> None:
        while (job := self._jobs.get()) is not None:
            text, seq = job
            try:
                from ncbot.speech.audio import write_wav
                from ncbot.speech.tts import ROBOT_VOICE, speak

                samples = speak(text, ROBOT_VOICE)
            except (ValueError, OSError, RuntimeError):
                self.available = False  # no TTS engine here: text alone from now on
                continue
            name = f"utterance-{self._count:04d}.wav"
            self._count += 1
            write_wav(self.folder / name, samples)
            self.on_ready(f"{self.url_prefix}/{name}", seq)


class BroadcastSpeaker:
    """Stands in for robot_sim's Speaker: keeps the text (as it does) and hands it to the session."""

    def __init__(self, on_say: Callable[[str], None], has_audio: bool) -> None:
        self.on_say = on_say
        self.has_audio = has_audio
        self.said: list[str] = []
        self.tts_seconds: list[float] = []  # as Speaker's; the browser speaks, so nothing is synthesised here

    def say(self, text: str) -> None:
        self.said.append(text)
        self.on_say(text)
