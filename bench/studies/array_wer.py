"""Word error rate against the SNR at Pepper's array, for babble and for diffuse noise: one microphone and the array
with each enhancement, on held-out voices, talkers and rooms; the CPU cost of each enhancement per utterance
against the recogniser's own in the same run; and the four presets' rooms at their own noise.

    python bench/studies/array_wer.py [--utterances 40] [--snr 0,5,10,15,20] [--rooms 6] [--room-preset atrium]
                                      [--set held-out|tuning] [--presets] [--geometry-scale 1.0] [--json F] [--png F]

Columns: "mono mix" = the one-microphone hearing (the noise mixed into the reply's own samples, no room: what
the recogniser was measured on before the array); "mic, reply" = the front-left microphone cut to exactly the
reply (the window a perfect endpointer would give); then the enhancement specs of ``--specs``
(``ncbot.speech.enhance``; ``none`` is that microphone's whole listening window), ``+vad`` cuts the reply out, ``ds``/``mvdr`` the beams (aimed where
the camera puts the person: across the table at an adult's mouth height), ``+doa`` aims by the array's own
estimate instead. The rooms, voices, talkers and seeds are the held-out set of ``ncbot.speech.trial_sets``
unless ``--set tuning``. Intervals: 95 % bootstrap over utterances.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.speech.acoustic_scene import camera_direction, draw_layout  # noqa: E402
from ncbot.speech.align import word_errors  # noqa: E402
from ncbot.speech.array import HOME_HEAD  # noqa: E402
from ncbot.speech.asr import Recogniser, dialogue_sentences  # noqa: E402
from ncbot.speech.ears import MonoEars  # noqa: E402
from ncbot.speech.enhance import Enhancement, Enhancer  # noqa: E402
from ncbot.speech.fit import babble_texts  # noqa: E402
from ncbot.speech.listening import ArrayRecorder  # noqa: E402
from ncbot.speech.room import Room  # noqa: E402
from ncbot.speech.roundtrip import babble_pool  # noqa: E402
from ncbot.speech.tts import SpeechCache  # noqa: E402
from ncbot.speech import trial_sets  # noqa: E402

SPECS = ("none+vad", "ds+vad", "mvdr+vad", "mvdr+vad+doa")
REFERENCES = ("mono mix", "mic, reply")
MARGIN = 800  # samples around the exact reply in "mic, reply" (50 ms), as an endpointer's margin


class Counts:
    """Per column: word errors and words per utterance, CPU seconds of the enhancement and of the decode."""

    def __init__(self, columns: tuple[str, ...]) -> None:
        self.errors: dict[str, list[tuple[int, int]]] = {c: [] for c in columns}
        self.cpu: dict[str, list[float]] = {c: [] for c in columns}
        self.asr_cpu: list[float] = []

    def wer(self, column: str, rng: np.random.Generator) -> tuple[float, float, float]:
        pairs = np.array(self.errors[column], dtype=np.float64)
        point = pairs[:, 0].sum() / pairs[:, 1].sum()
        draws = rng.integers(len(pairs), size=(1000, len(pairs)))
        boot = pairs[draws, 0].sum(1) / pairs[draws, 1].sum(1)
        return float(point), float(np.quantile(boot, 0.025)), float(np.quantile(boot, 0.975))


def decode(recogniser: Recogniser, samples: np.ndarray, said: list[str], counts: Counts, column: str) -> None:
    started = time.process_time()
    heard = recogniser.recognise(samples)
    counts.asr_cpu.append(time.process_time() - started)
    counts.errors[column].append((word_errors(said, heard.words), len(said)))


def rooms_of(ranges, count: int, seed: int, scale: float) -> list[Room]:
    return [Room(draw_layout(ranges, np.random.default_rng([seed, i]), HOME_HEAD), scale) for i in range(count)]


def run_block(kind: str, items: list[tuple[Room, str, object, float | None]], pool, cache: SpeechCache, seed: int,
              counts: Counts, specs: tuple[str, ...]) -> None:
    """One block of (room, text, voice, SNR) utterances in `kind` noise: each recorded once at the array and heard
    by every column (each column its own recogniser, as a robot with those ears would have)."""
    from ncbot.speech.enhance import to_int16

    recognisers = {c: Recogniser() for c in counts.errors}
    enhancers = {spec: Enhancer(Enhancement.parse(spec), items[0][0].mics) for spec in specs}
    for i, (room, text, voice, snr) in enumerate(items):
        said = text.split()
        clean, _ = cache.speak(text, voice)
        rng = np.random.default_rng([seed, i])
        take = ArrayRecorder(room, kind, pool).record(clean, snr, rng)
        decode(recognisers["mono mix"], MonoEars(kind, pool).take(clean, snr, rng).samples, said, counts, "mono mix")
        start, stop = take.speech_span
        reply = to_int16(take.channels[0, max(start - MARGIN, 0):stop + MARGIN].astype(np.float64))
        decode(recognisers["mic, reply"], reply, said, counts, "mic, reply")
        camera = camera_direction(HOME_HEAD, room.mics, 0.0)
        for spec, enhancer in enhancers.items():
            enhancer.mics = room.mics
            enhanced = enhancer(take.channels, camera)
            counts.cpu[spec].append(enhanced.cpu_s)
            decode(recognisers[spec], enhanced.samples, said, counts, spec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--utterances", type=int, default=40, help="per noise kind and SNR level")
    parser.add_argument("--snr", default="0,5,10,15,20")
    parser.add_argument("--kinds", default="babble,white")
    parser.add_argument("--rooms", type=int, default=6)
    parser.add_argument("--room-preset", default="atrium", help="the held-out rooms' preset (robot_sim.conditions)")
    parser.add_argument("--set", choices=("held-out", "tuning"), default="held-out")
    parser.add_argument("--presets", action="store_true", help="also each preset's rooms at its own noise")
    parser.add_argument("--geometry-scale", type=float, default=1.0)
    parser.add_argument("--specs", default=",".join(SPECS), help="enhancements to compare (speech.enhance specs)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--png", type=Path)
    args = parser.parse_args()
    from ncbot.robot_sim.conditions import PRESETS

    tuning = args.set == "tuning"
    seed = trial_sets.TUNING_SEED if tuning else trial_sets.HELD_OUT_SEED
    voices = trial_sets.TUNING_VOICES if tuning else trial_sets.HELD_OUT_VOICES
    pool = babble_pool(babble_texts(), trial_sets.TUNING_BABBLE_VOICES if tuning else trial_sets.HELD_OUT_BABBLE_VOICES)
    ranges = trial_sets.TUNING_ROOMS if tuning else PRESETS[args.room_preset].acoustics()
    turns, cache = dialogue_sentences(), SpeechCache()
    texts = [turns[i] for i in np.random.default_rng(seed).integers(len(turns), size=args.utterances)]
    print(f"{args.set} set: {args.utterances} utterances per cell, {args.rooms} rooms "
          f"({'tuning' if tuning else args.room_preset} ranges), geometry x{args.geometry_scale:g}, load "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    started = time.process_time()
    rooms = rooms_of(ranges, args.rooms, seed + 7, args.geometry_scale)
    print("rooms: " + ", ".join(f"{r.layout.dimensions[0]:.0f}x{r.layout.dimensions[1]:.0f}x{r.layout.dimensions[2]:.1f} m "
                                f"RT60 {r.measured_rt60:.2f} s, {len(r.layout.talkers)} talkers" for r in rooms)
          + f" ({time.process_time() - started:.1f} CPU s)", flush=True)
    results, rng, blocks = [], np.random.default_rng(seed), []
    utterance = lambda i, block_rooms: (block_rooms[i % len(block_rooms)], texts[i], voices[i % len(voices)])  # noqa: E731
    for kind in args.kinds.split(","):
        for snr in (float(v) for v in args.snr.split(",")):
            blocks.append((kind, f"{snr:g}", kind, [(*utterance(i, rooms), snr) for i in range(len(texts))]))
    if args.presets:  # each preset's rooms, its first noise kind, an SNR drawn per utterance in its range
        for name in ("lab", "office", "atrium", "random"):
            preset, draw = PRESETS[name], np.random.default_rng([seed, 5])
            preset_rooms = rooms_of(preset.acoustics(), 3, seed + 11, 1.0)
            low_high = preset.speech_snr_db
            items = [(*utterance(i, preset_rooms), None if low_high is None else float(draw.uniform(*low_high)))
                     for i in range(len(texts))]
            blocks.append((name, "clean" if low_high is None else "{:g}-{:g}".format(*low_high), preset.speech_noise[0],
                           items))
    specs = tuple(args.specs.split(","))
    columns = REFERENCES + specs
    header = f"{'kind':<8}{'SNR':>9} " + "".join(f"{c:>21}" for c in columns)
    print(header, flush=True)
    for number, (label, snr_label, kind, items) in enumerate(blocks):
        counts, wall = Counts(columns), time.time()
        run_block(kind, items, pool, cache, seed + 1000 * number, counts, specs)
        row = {"kind": label, "snr_db": snr_label, "utterances": len(items),
               "wer": {c: counts.wer(c, rng) for c in columns},
               "enhancement_cpu_s": {c: float(np.mean(v)) for c, v in counts.cpu.items() if v},
               "asr_cpu_s": float(np.mean(counts.asr_cpu))}
        results.append(row)
        print(f"{label:<8}{snr_label:>9} " + "".join(
            f"{w:>9.3f} [{lo:.2f},{hi:.2f}]" for w, lo, hi in row["wer"].values())
            + f"   ({time.time() - wall:.0f} s, block {number + 1}/{len(blocks)})", flush=True)
    cpu = {c: float(np.mean([r["enhancement_cpu_s"][c] for r in results if c in r["enhancement_cpu_s"]])) for c in specs}
    asr = float(np.mean([r["asr_cpu_s"] for r in results]))
    print(f"CPU s per utterance (same run): recogniser {asr:.4f}; enhancement "
          + ", ".join(f"{c} {v:.4f} ({v / asr:.2f}x the recogniser)" for c, v in cpu.items()), flush=True)
    if args.json:
        args.json.write_text(json.dumps({"set": args.set, "rooms": [r.layout.dimensions for r in rooms],
                                         "rt60": [r.measured_rt60 for r in rooms], "results": results,
                                         "enhancement_cpu_s": cpu, "asr_cpu_s": asr}, indent=1))
    if args.png:
        plot(results, args.png)


def plot(results: list[dict], path: Path) -> None:
    """WER against SNR per column, one panel per noise kind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = [k for k in ("babble", "white") if any(r["kind"] == k for r in results)]
    figure, axes = plt.subplots(1, len(kinds), figsize=(6 * len(kinds), 4.2), squeeze=False)
    for axis, kind in zip(axes[0], kinds):
        rows = [r for r in results if r["kind"] == kind]
        snr = [float(r["snr_db"]) for r in rows]
        for column in rows[0]["wer"]:
            wer = [r["wer"][column] for r in rows]
            axis.errorbar(snr, [w[0] for w in wer], yerr=[[w[0] - w[1] for w in wer], [w[2] - w[0] for w in wer]],
                          marker="o", capsize=2, label=column)
        axis.set_title(f"{'babble talkers' if kind == 'babble' else 'diffuse noise'} at Pepper's array")
        axis.set_xlabel("SNR at the array (dB)")
        axis.set_ylabel("word error rate")
        axis.set_ylim(0, 1.2)
        axis.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
