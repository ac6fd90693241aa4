"""The robot's voice and ears in a game: the robot speaks its templates, the simulated person answers with
another voice over the room's background noise, and the real recogniser hears the answer.

`Speaker` keeps every utterance's text (what `/dialogue` logs) and, with a voice, synthesises it (speech.tts,
cached per text and voice). `GameSpeech` holds what all games of a run share (the pocketsphinx recognisers,
the TTS cache, the babble talkers' audio) and builds each game's ears: a `ncbot.speech.hearing.RecogniserHearing`
that the dialogue env takes as its `hearing` (the same hook `env.asr: channel` uses in training), and the
`ncbot.speech.cell_answers.AnswerEars` that hear the answer to "where did you draw?" (robot_sim.where).

Held out from the channel model's fit (speech/fit.py, docs/speech.md): the person is one of the four flite voices
at their normal rate (the fit heard them at 0.85 and 1.15), babble comes from the report set of espeak-ng
talkers, and the noise is drawn from `SeedSequence([game seed, NOISE_SALT])` (the fit's noise came from single
integer seeds from 1 000 000).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ncbot.robot_sim.conditions import ConditionRanges

# SeedSequence words that keep the game's speech draws apart from its others (and the answers' noise apart
# from the dialogue's, so a game's dialogue is heard the same with or without unseen moves)
PERSON_SALT, NOISE_SALT, ANSWER_NOISE_SALT = 150, 151, 152


class Speaker:
    """Says template utterances: keeps the text; with `voice` (a `ncbot.speech.tts.Voice`) it synthesises them and
    returns the samples; with `audio_dir` too it writes one WAV per utterance (`utterance-NNNN.wav`)."""

    def __init__(self, audio_dir: str | Path | None = None, voice=None, cache=None) -> None:
        from ncbot.speech.tts import SpeechCache

        self.voice = voice
        self.cache = cache if cache is not None else SpeechCache()
        self.audio_dir = Path(audio_dir) if audio_dir is not None and voice is not None else None
        if self.audio_dir is not None:
            self.audio_dir.mkdir(parents=True, exist_ok=True)
        self.said: list[str] = []
        #: wall seconds of each synthesis (0-ish when it came from the cache)
        self.tts_seconds: list[float] = []

    @property
    def has_audio(self) -> bool:
        return self.voice is not None

    def say(self, text: str) -> np.ndarray | None:
        """Record `text`; with a voice, return its samples (int16, 16 kHz mono; None for empty text)."""
        self.said.append(text)
        if self.voice is None or not text.strip():
            return None
        started = time.perf_counter()
        samples, _ = self.cache.speak(text, self.voice)
        self.tts_seconds.append(time.perf_counter() - started)
        if self.audio_dir is not None:
            from ncbot.speech.audio import write_wav

            write_wav(self.audio_dir / f"utterance-{len(self.said) - 1:04d}.wav", samples)
        return samples


class GameSpeech:
    """The speech parts every game of a run shares, and each game's ears drawn from its seed."""

    def __init__(self, game: str, ranges: ConditionRanges) -> None:
        from ncbot.envs.dialogue import build_dialogue_model
        from ncbot.robot_sim.scene import check_game
        from ncbot.speech.asr import Recogniser
        from ncbot.speech.cell_answers import answer_sentences, confirm_sentences
        from ncbot.speech.fit import REPORT_BABBLE_VOICES, babble_texts
        from ncbot.speech.roundtrip import babble_pool
        from ncbot.speech.tts import SpeechCache

        dialogue = build_dialogue_model(game)
        self.texts, self.words = dialogue.utterance_texts, dialogue.words
        self.ranges = ranges
        self.recogniser = Recogniser()
        self.grid = check_game(game)
        # the answers to "where did you draw?" and "did you say ...?" each have their own small LM
        self.cell_recogniser = Recogniser(answer_sentences(self.grid))
        self.confirm_recogniser = Recogniser(confirm_sentences())
        self.cache = SpeechCache()
        noisy_babble = ranges.speech_snr_db is not None and "babble" in ranges.speech_noise
        self.babble_pool = babble_pool(babble_texts(), REPORT_BABBLE_VOICES) if noisy_babble else []

    def hearing(self, seed: int):
        """The ears of the game with `seed`: its person's voice and noise kind drawn once, SNR per utterance."""
        from ncbot.speech.fit import REPORT_VOICES
        from ncbot.speech.hearing import RecogniserHearing

        rng = np.random.default_rng([seed, PERSON_SALT])
        voice = REPORT_VOICES[int(rng.integers(len(REPORT_VOICES)))]
        kind = self.ranges.speech_noise[int(rng.integers(len(self.ranges.speech_noise)))]
        snr = self.ranges.speech_snr_db
        self.recogniser.reset()  # the game's ears start fresh: its hearing depends on its seed alone
        return RecogniserHearing(self.texts, self.words, self.recogniser, voice=voice,
                                 snr_db=None if snr is None else (float(snr[0]), float(snr[1])), kind=kind,
                                 babble_pool=self.babble_pool, seed=[seed, NOISE_SALT], cache=self.cache)

    def answer_ears(self, seed: int, hearing):
        """The ears for the game's answers to "where did you draw?": the same person, noise kind and SNR range as
        `hearing` (this game's), the noise from its own seed, the answers' recognisers started afresh."""
        from ncbot.speech.cell_answers import AnswerEars

        self.cell_recogniser.reset()
        self.confirm_recogniser.reset()
        return AnswerEars(self.grid, self.cell_recogniser, self.confirm_recogniser, voice=hearing.voice, snr_db=hearing.snr_db,
                          kind=hearing.kind, babble_pool=self.babble_pool, seed=[seed, ANSWER_NOISE_SALT],
                          cache=self.cache)


class SpeechLog:
    """One game's speech into the MCAP log and its `GameRecord`: each utterance on `/audio/robot` or `/audio/user`
    (`foxglove.RawAudio`) at the speech clock, noted on the speaker's next `/dialogue` turn with its text (the
    person's also with what the recogniser heard, per-word confidences and the SNR), and the ASR counts."""

    def __init__(self, logger, record) -> None:
        self.logger, self.record = logger, record
        self.clock = 0.0  # scene seconds when the last utterance ends: utterances never overlap in the log
        self.notes: dict[str, list[dict]] = {}
        self.answers: list[dict] = []  # this step's answers to "where did you draw?" (their /dialogue note)

    def utterance(self, speaker: str, samples: np.ndarray, text: str, scene_time: float, count: bool = True) -> float:
        """Log one utterance starting at `scene_time` (or when the one before ends); returns its timestamp.
        `count`: add it to the record's utterances per speaker (the dialogue's; answers are counted apart)."""
        from ncbot.speech import SAMPLE_RATE
        from ncbot.speech.audio import AUDIO_TOPICS, raw_audio

        t = max(scene_time, self.clock)
        seconds = samples.size / SAMPLE_RATE
        self.clock = t + seconds
        if count:
            self.record.utterances[speaker] = self.record.utterances.get(speaker, 0) + 1
        if self.logger is not None:
            self.logger.log_audio(raw_audio(samples), topic=AUDIO_TOPICS[speaker], t=t)
            self.notes.setdefault(speaker, []).append(
                {"topic": AUDIO_TOPICS[speaker], "t": round(t, 4), "seconds": round(seconds, 4), "text": text})
        return t

    def heard(self, hearing, heard: list, scene_time: float) -> None:
        """The person's replies `hearing` (a `RecogniserHearing`) heard in the last env step."""
        from ncbot.speech.align import word_errors

        record = self.record
        for utterance in heard:
            self.utterance("user", utterance.samples, utterance.said, scene_time)
            said = utterance.said.split()
            record.asr_words += len(said)
            record.asr_word_errors += word_errors(said, utterance.heard.words)
            record.asr_confidences.extend(utterance.heard.confidences)
            understood = utterance.understood
            record.asr_understood += int(understood >= 0 and hearing.texts[understood] == utterance.said)
            record.person_tts_seconds.append(utterance.tts_wall_s)
            record.asr_seconds.append(utterance.asr_wall_s)
            record.asr_cpu_seconds.append(utterance.asr_cpu_s)
            if self.logger is not None:
                self.logger.note_dialogue("user", heard=utterance.heard.text, snr_db=utterance.snr_db,
                                          heard_words=[[w, round(c, 3)] for w, c in
                                                       zip(utterance.heard.words, utterance.heard.confidences)])

    def answer(self, utterance, question: str, scene_time: float) -> None:
        """One of the person's answers to the robot's `question` about an unseen move (a `HeardUtterance` whose
        `understood` is the cell heard): audio on `/audio/user`, words and cell on the user's `/dialogue` turn."""
        from ncbot.speech.align import word_errors

        t = self.utterance("user", utterance.samples, utterance.said, scene_time, count=False)
        record = self.record
        record.cell_answers += 1
        record.cell_answer_words += len(utterance.said.split())
        record.cell_answer_word_errors += word_errors(utterance.said.split(), utterance.heard.words)
        record.cell_answer_cpu_seconds.append(utterance.asr_cpu_s)
        if self.logger is not None:
            self.answers.append({"question": question, "said": utterance.said, "heard": utterance.heard.text,
                                 "heard_words": [[w, round(c, 3)] for w, c in
                                                 zip(utterance.heard.words, utterance.heard.confidences)],
                                 "understood": utterance.understood, "snr_db": utterance.snr_db, "t": round(t, 4)})

    def flush(self) -> None:
        """Hand the utterances' notes to the logger before the step's /dialogue turns are written."""
        if self.logger is not None:
            for speaker, audio in self.notes.items():
                self.logger.note_dialogue(speaker, audio=audio)
            if self.answers:
                self.logger.note_dialogue("user", cell_answers=self.answers)
        self.notes, self.answers = {}, []
