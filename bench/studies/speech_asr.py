"""The recogniser on the example dialogues: word error rate and mean word confidence per noise condition, CPU
per utterance for TTS and ASR, and the fitted channel model's figures on the same utterances beside the real ones.

    python bench/studies/speech_asr.py [--utterances 240] [--channel speech/data/asr_channel.json]

Utterances are drawn (seed REPORT_SEED) from every user turn of the example dialogues, so frequent replies count
as often as they are said; the person's voices, noise seeds and babble talkers are the report set of
speech/fit.py, apart from those the channel model was fitted on.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.speech.align import word_errors  # noqa: E402
from ncbot.speech.asr import Heard, Recogniser, dialogue_sentences  # noqa: E402
from ncbot.speech.channel import DEFAULT_CHANNEL, ChannelModel  # noqa: E402
from ncbot.speech.fit import REPORT_BABBLE_VOICES, REPORT_SEED, REPORT_VOICES, babble_texts  # noqa: E402
from ncbot.speech.roundtrip import RoundTripper, Trial, babble_pool  # noqa: E402
from ncbot.speech import SAMPLE_RATE  # noqa: E402
from ncbot.speech.tts import ROBOT_VOICE, speak_timed  # noqa: E402
from ncbot.speech.understand import closest_text  # noqa: E402

CONDITIONS: tuple[tuple[str, float | None], ...] = (
    ("white", None), ("white", 20.0), ("white", 10.0), ("babble", 20.0), ("babble", 10.0)
)


def summary(said: list[tuple[str, ...]], heard: list[Heard], texts: list[str]) -> tuple[float, float, float, float]:
    """Word error rate, mean confidence of the words heard, share of utterances heard as nothing, share
    understood as the utterance said (closest of the distinct user sentences ``texts``)."""
    errors = sum(word_errors(s, h.words) for s, h in zip(said, heard))
    confidences = [c for h in heard for c in h.confidences]
    understood = [closest_text(h.words, h.confidences, texts) for h in heard]
    return (
        errors / sum(len(s) for s in said),
        float(np.mean(confidences)) if confidences else 0.0,
        sum(1 for h in heard if not h.words) / len(heard),
        float(np.mean([u >= 0 and texts[u].split() == list(s) for u, s in zip(understood, said)])),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--utterances", type=int, default=240)
    parser.add_argument("--channel", type=Path, default=DEFAULT_CHANNEL)
    args = parser.parse_args()
    rng = np.random.default_rng(REPORT_SEED)
    turns = dialogue_sentences()
    texts = [turns[i] for i in rng.integers(len(turns), size=args.utterances)]
    voices = [REPORT_VOICES[i % len(REPORT_VOICES)] for i in range(args.utterances)]
    print(f"{args.utterances} utterances ({len(set(texts))} distinct) drawn from {len(turns)} user turns; "
          f"voices {', '.join(v.name for v in REPORT_VOICES)}; load average {os.getloadavg()[0]:.1f}")

    started = time.process_time()
    recogniser = Recogniser()
    print(f"recogniser set-up: {time.process_time() - started:.2f} CPU s (LM of {len(turns)} sentences, "
          f"{len(recogniser.vocabulary)} words)")
    tripper = RoundTripper(recogniser, babble_pool(babble_texts(), REPORT_BABBLE_VOICES))
    channel = ChannelModel.load(args.channel)
    generator = torch.Generator().manual_seed(REPORT_SEED)

    distinct = sorted(set(turns))
    print(f"{'':<14}{'real recogniser':^28}   {'channel model':^32}")
    print(f"{'condition':<14}{'WER':>7}{'conf':>7}{'empty':>7}{'undst':>7}   {'WER':>11}{'conf':>7}{'empty':>7}{'undst':>7}")
    tts_cpu, asr_cpu = [], []
    for number, (kind, snr) in enumerate(CONDITIONS):
        trials = [Trial(t, v, kind, snr, REPORT_SEED + number * 100_000 + i) for i, (t, v) in enumerate(zip(texts, voices))]
        trips = tripper.run_all(trials)
        tts_cpu += [t.tts_cpu_s for t in trips if t.tts_cpu_s > 0]
        asr_cpu += [t.asr_cpu_s for t in trips]
        said = [t.said for t in trips]
        real = summary(said, [t.heard for t in trips], distinct)
        sampled = summary(said, channel.sample_heard(texts, snr, kind, generator), distinct)
        name = "clean" if snr is None else f"{kind} {snr:g} dB"
        print(f"{name:<14}" + "".join(f"{x:7.3f}" for x in real) + f"   {sampled[0]:11.3f}"
              + "".join(f"{x:7.3f}" for x in sampled[1:]))

    templates = babble_texts()[:10]
    robot = [speak_timed(t, ROBOT_VOICE) for t in templates]
    seconds = sum(samples.size for samples, _ in robot) / SAMPLE_RATE / len(templates)
    robot_cpu = float(np.mean([cpu for _, cpu in robot]))
    print(f"CPU s per utterance: person TTS (flite) {np.mean(tts_cpu):.4f} over {len(tts_cpu)} syntheses, "
          f"robot TTS (espeak-ng) {robot_cpu:.4f} over {len(templates)} templates ({seconds:.1f} s of "
          f"speech each), ASR {np.mean(asr_cpu):.4f} (median {np.median(asr_cpu):.4f}, max {np.max(asr_cpu):.4f}) "
          f"over {len(asr_cpu)} decodes")

    batch = 4096
    said = channel.encode(texts[:1] * batch)
    snr = torch.full((batch,), 15.0)
    channel.sample(said, snr, "babble", generator)
    torch.set_num_threads(1)
    started = time.process_time()
    for _ in range(20):
        channel.sample(said, snr, "babble", generator)
    per_call = (time.process_time() - started) / 20
    print(f"channel sampler (1 thread): {per_call * 1e3:.2f} CPU ms per batch of {batch} utterances "
          f"({per_call / batch * 1e6:.2f} us each), model file {args.channel.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
