"""Which voices, babble talkers, rooms and noise seeds choose things (the answer thresholds, the enhancement's
settings) and which measure them: the two sets never share a voice, a talker, a room or a seed.

TUNING (choosing): the person's flite voices slowed and sped up (rate 0.85 / 1.15, the channel model's fit voices),
babble talkers espeak-ng `en-us+m3`, `en-gb+f2`, `en+m1`, rooms drawn from `TUNING_ROOMS` with seeds from
`TUNING_SEED` (sizes and reverberation spanning the presets' rooms), noise seeds from `TUNING_SEED` too.
HELD OUT (measuring: ``bench/studies/array_wer.py``, ``answers_flow.py``, ``ncbot robot play``): the four flite voices
at their normal rate, babble talkers espeak-ng `en-us+f3`, `en-gb-scotland+m2`, `en+f4`, the presets' rooms drawn
from game seeds (robot play: `SeedSequence([game seed, 153])`; benches: seeds from `HELD_OUT_SEED`).
"""
from __future__ import annotations

from ncbot.speech.acoustic_scene import AcousticRanges
from ncbot.speech.fit import FIT_BABBLE_VOICES, FIT_VOICES, REPORT_BABBLE_VOICES, REPORT_VOICES

TUNING_VOICES, TUNING_BABBLE_VOICES = FIT_VOICES, FIT_BABBLE_VOICES
HELD_OUT_VOICES, HELD_OUT_BABBLE_VOICES = REPORT_VOICES, REPORT_BABBLE_VOICES
TUNING_SEED, HELD_OUT_SEED = 3_000_000, 0
#: Tuning rooms: from a small office to a hall, dry to reverberant, with one to seven talkers.
TUNING_ROOMS = AcousticRanges(room_size=((5.0, 22.0), (4.5, 18.0), (2.7, 9.0)), rt60=(0.3, 1.4), talkers=(1, 7),
                              talker_distance=(1.3, 5.5), mouth_height=(1.15, 1.7), person_offset=(-0.3, 0.3))
