"""ncbot speech: offline text-to-speech (flite, espeak-ng), background noise, a pocketsphinx recogniser with a
small language model of the example dialogues, and an ASR channel model fitted from real round trips so the
training env can hear "like the recogniser" without running it.

Layer: imports ``envs`` (the example dialogues) and ``fileio`` only. Audio is always 16 kHz mono int16 (``SAMPLE_RATE``).
"""
from __future__ import annotations

SAMPLE_RATE = 16_000
