"""The robot's voice and ears in a game: the robot speaks its templates, the simulated person answers with
another voice over the room's background noise, and the real recogniser hears the answer.

`Speaker` keeps every utterance's text (what `/dialogue` logs) and, with a voice, synthesises it (speech.tts,
cached per text and voice). `GameSpeech` holds what all games of a run share (the pocketsphinx recognisers,
the TTS cache, the babble talkers' audio) and builds each game's ears: a `ncbot.speech.hearing.RecogniserHearing`
that the dialogue env takes as its `hearing` (the same hook `env.asr: channel` uses in training), and the
`ncbot.speech.cell_answers.AnswerEars` that hear the answer to "where did you draw?" (robot_sim.where). With
`ears="array"` both hear through Pepper's four head microphones in the game's room (`ncbot.speech.ears.ArrayEars`:
the room drawn from the conditions and the game's seed, the person across the table from the robot, a bystander
of the scene among the talkers), the beam aimed where the robot's camera found the sheet (`aim`).

Held out from the channel model's fit (speech/fit.py, docs/speech.md): the person is one of the four flite voices
at their normal rate (the fit heard them at 0.85 and 1.15), babble comes from the report set of espeak-ng
talkers, and the noise is drawn from `SeedSequence([game seed, NOISE_SALT])` (the fit's noise came from single
integer seeds from 1 000 000).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.robot_sim.conditions import ConditionRanges

# SeedSequence words that keep the game's speech draws apart from its others (and the answers' noise apart
# from the dialogue's, so a game's dialogue is heard the same with or without unseen moves)
PERSON_SALT, NOISE_SALT, ANSWER_NOISE_SALT, ROOM_SALT = 150, 151, 152, 153
EARS = ("array", "mono")
#: Where a bystander's mouth is (robot frame, m): `ncbot.robot_sim.dressing` stands them at (0.9, 0.9), head at 1.68 m.
BYSTANDER_MOUTH = (0.9, 0.9, 1.6)


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

    @classmethod
    def for_robot(cls, audio_dir: Path | None, speech: GameSpeech | None) -> Speaker:
        """The robot's voice: espeak-ng with real speech (or for --audio WAVs when installed), else text only."""
        import shutil

        from ncbot.speech.tts import ROBOT_VOICE

        if speech is not None:
            return cls(audio_dir, ROBOT_VOICE, speech.cache)
        return cls(audio_dir, ROBOT_VOICE if audio_dir and shutil.which("espeak-ng") else None)

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

    def __init__(self, game: str, ranges: ConditionRanges, ears: str = "mono", enhancement: str = "mvdr+vad") -> None:
        from ncbot.envs.dialogue import build_dialogue_model
        from ncbot.robot_sim.scene import check_game
        from ncbot.speech.asr import Recogniser
        from ncbot.speech.cell_answers import answer_sentences, confirm_sentences
        from ncbot.speech.fit import REPORT_BABBLE_VOICES, babble_texts
        from ncbot.speech.roundtrip import babble_pool
        from ncbot.speech.tts import SpeechCache

        from ncbot.speech.enhance import Enhancement

        if ears not in EARS:
            raise ValueError(f"ears must be one of {', '.join(EARS)}; got {ears!r}")
        dialogue = build_dialogue_model(game)
        self.texts, self.words = dialogue.utterance_texts, dialogue.words
        self.ranges, self.ears, self.enhancement = ranges, ears, Enhancement.parse(enhancement)
        #: how cells said aloud are settled (robot_sim.where): None = confirm every cell
        self.thresholds = None
        self.recogniser = Recogniser()
        self.grid = check_game(game)
        # the answers to "where did you draw?" and "did you say ...?" each have their own small LM
        self.cell_recogniser = Recogniser(answer_sentences(self.grid))
        self.confirm_recogniser = Recogniser(confirm_sentences())
        self.cache = SpeechCache()
        noisy_babble = ranges.speech_snr_db is not None and "babble" in ranges.speech_noise
        self.babble_pool = babble_pool(babble_texts(), REPORT_BABBLE_VOICES) if noisy_babble else []

    @classmethod
    def for_play(cls, config) -> GameSpeech:
        """The speech of a `RobotPlayConfig` with real speech: its ears, enhancement and answer thresholds."""
        from ncbot.speech.answer_policy import DEFAULT_THRESHOLDS, AnswerThresholds

        speech = cls(config.game, config.condition_ranges(), config.ears, config.enhancement)
        if config.answers == "confidence":
            speech.thresholds = AnswerThresholds.load(config.answer_thresholds or DEFAULT_THRESHOLDS)
        return speech

    def game_hearing(self, seed: int, scene):
        """`hearing` for the game being played in `scene`: the robot's head as it is, the person across the table
        from the sheet as it was laid, the scene's bystander among the talkers."""
        return self.hearing(seed, head_pose(scene), float(scene.sheet_home_pose.p[1]), scene.conditions.bystander)

    def hearing(self, seed: int, head=None, person_y: float = 0.0, bystander: bool = False):
        """The ears of the game with `seed`: its person's voice and noise kind drawn once, SNR per utterance; with
        the array, its room (the robot's `head` pose, `ncbot.speech.array.HeadPose`; the person across the table on
        the sheet's centre line `person_y`; a `bystander` among the talkers)."""
        from ncbot.speech.fit import REPORT_VOICES
        from ncbot.speech.hearing import RecogniserHearing

        rng = np.random.default_rng([seed, PERSON_SALT])
        voice = REPORT_VOICES[int(rng.integers(len(REPORT_VOICES)))]
        kind = self.ranges.speech_noise[int(rng.integers(len(self.ranges.speech_noise)))]
        snr = self.ranges.speech_snr_db
        ears = self.array_ears(seed, kind, head, person_y, bystander) if self.ears == "array" else None
        self.recogniser.reset()  # the game's ears start fresh: its hearing depends on its seed alone
        return RecogniserHearing(self.texts, self.words, self.recogniser, voice=voice,
                                 snr_db=None if snr is None else (float(snr[0]), float(snr[1])), kind=kind,
                                 babble_pool=self.babble_pool, seed=[seed, NOISE_SALT], cache=self.cache, ears=ears)

    def array_ears(self, seed: int, kind: str, head=None, person_y: float = 0.0, bystander: bool = False):
        """Pepper's array in the game's room, drawn from the conditions with `SeedSequence([seed, ROOM_SALT])`;
        the beam has no camera direction yet (`aim` gives it once the robot has seen the sheet)."""
        from ncbot.speech.acoustic_scene import draw_layout
        from ncbot.speech.array import HOME_HEAD
        from ncbot.speech.ears import ArrayEars
        from ncbot.speech.room import Room

        layout = draw_layout(self.ranges.acoustics(), np.random.default_rng([seed, ROOM_SALT]), head or HOME_HEAD,
                             person_y, (BYSTANDER_MOUTH,) if bystander else ())
        return ArrayEars(Room(layout), kind, self.babble_pool, self.enhancement)

    def answer_ears(self, seed: int, hearing):
        """The ears for the game's answers to "where did you draw?": the same person, noise kind, SNR range and
        ears (one microphone, or the array in the same room) as `hearing` (this game's), the noise from its own
        seed, the answers' recognisers started afresh."""
        from ncbot.speech.cell_answers import AnswerEars

        self.cell_recogniser.reset()
        self.confirm_recogniser.reset()
        return AnswerEars(self.grid, self.cell_recogniser, self.confirm_recogniser, voice=hearing.voice, snr_db=hearing.snr_db,
                          kind=hearing.kind, babble_pool=self.babble_pool, seed=[seed, ANSWER_NOISE_SALT],
                          cache=self.cache, ears=hearing.ears)


def head_pose(scene):
    """Pepper's head in `scene` now (`ncbot.speech.array.HeadPose`): the Head link's position, the base's yaw plus
    HeadYaw, and HeadPitch."""
    from ncbot.speech.array import HeadPose

    q = scene.qpos
    position = tuple(float(v) for v in scene.link_pose("Head").p)
    yaw = float(scene.base_pose()[2]) + float(q[scene.joint_index["HeadYaw"]])
    return HeadPose(position, yaw, float(q[scene.joint_index["HeadPitch"]]))


def aim(hearing, sheet_estimate) -> None:
    """Aim an array's beam across the table from the sheet the camera localised (no hearing, or mono ears: nothing
    to aim)."""
    from ncbot.speech.acoustic_scene import camera_direction
    from ncbot.speech.ears import ArrayEars

    ears = getattr(hearing, "ears", None)
    if isinstance(ears, ArrayEars) and sheet_estimate is not None:
        ears.camera_direction = camera_direction(ears.room.layout.head, ears.room.mics, float(sheet_estimate.centre[1]))


def speech_summary(hearing) -> dict[str, Any]:
    """What a game's person and ears were, as `game_conditions[i].speech` reports it (the room: the array only)."""
    summary = {"voice": hearing.voice.spec, "noise": hearing.kind, "snr_db": hearing.snr_db}
    room = getattr(hearing.ears, "room", None)
    if room is None:
        return summary
    layout = room.layout
    return {**summary, "room": {"size_m": [round(v, 2) for v in layout.dimensions], "rt60_s": round(layout.rt60, 2),
                     "measured_rt60_s": round(room.measured_rt60, 2), "talkers": len(layout.talkers),
                     "mouth_m": [round(v, 2) for v in layout.mouth]}}



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
        """Log one utterance (int16 mono, or (channels, n) for what Pepper's array took in) starting at `scene_time`
        (or when the one before ends); returns its timestamp. `count`: add it to the record's utterances per
        speaker (the dialogue's; answers are counted apart)."""
        from ncbot.speech import SAMPLE_RATE
        from ncbot.speech.audio import AUDIO_TOPICS, raw_audio

        t = max(scene_time, self.clock)
        seconds = samples.shape[-1] / SAMPLE_RATE
        self.clock = t + seconds
        if count:
            self.record.utterances[speaker] = self.record.utterances.get(speaker, 0) + 1
        if self.logger is not None:
            self.logger.log_audio(raw_audio(samples), topic=AUDIO_TOPICS[speaker], t=t)
            self.notes.setdefault(speaker, []).append(
                {"topic": AUDIO_TOPICS[speaker], "t": round(t, 4), "seconds": round(seconds, 4), "text": text})
        return t

    def _reply(self, utterance, scene_time: float, count: bool = True) -> tuple[float, dict | None]:
        """One reply as the microphones took it in (and, with the array, its enhanced mono on
        `/audio/user/enhanced` at the same time); the array's work counted in the record. Returns its timestamp
        and the `/dialogue` note of the array's work (None for one microphone)."""
        from ncbot.speech import SAMPLE_RATE
        from ncbot.speech.audio import AUDIO_TOPICS, raw_audio

        t = self.utterance("user", utterance.channels, utterance.said, scene_time, count)
        take = utterance.take
        if take is None or take.enhanced is None:
            return t, None
        enhanced, record = take.enhanced, self.record
        record.enhancement_cpu_seconds.append(enhanced.cpu_s)
        if enhanced.steered_by is not None:
            record.steered_by[enhanced.steered_by] = record.steered_by.get(enhanced.steered_by, 0) + 1
            record.beam_errors_deg.append(take.beam_error_deg)
        if self.logger is not None:
            self.logger.log_audio(raw_audio(utterance.samples), topic=AUDIO_TOPICS["enhanced"], t=t)
        span = None if enhanced.span is None else [round(v / SAMPLE_RATE, 3) for v in enhanced.span]
        return t, {"steered_by": enhanced.steered_by, "span": span, "enhancement_cpu_s": round(enhanced.cpu_s, 4),
                   "beam_error_deg": None if take.beam_error_deg is None else round(take.beam_error_deg, 1)}

    def heard(self, hearing, heard: list, scene_time: float) -> bool:
        """The person's replies `hearing` (a `RecogniserHearing`) heard in the last env step; whether the robot
        understood every one as the utterance said (False: one was heard as nothing or as another utterance)."""
        from ncbot.speech.align import word_errors

        record, all_understood = self.record, True
        for utterance in heard:
            _, ears = self._reply(utterance, scene_time)
            said = utterance.said.split()
            record.asr_words += len(said)
            record.asr_word_errors += word_errors(said, utterance.heard.words)
            record.asr_confidences.extend(utterance.heard.confidences)
            understood = utterance.understood
            understood_as_said = understood >= 0 and hearing.texts[understood] == utterance.said
            record.asr_understood += int(understood_as_said)
            all_understood &= understood_as_said
            record.person_tts_seconds.append(utterance.tts_wall_s)
            record.asr_seconds.append(utterance.asr_wall_s)
            record.asr_cpu_seconds.append(utterance.asr_cpu_s)
            if self.logger is not None:
                self.logger.note_dialogue("user", heard=utterance.heard.text, snr_db=utterance.snr_db,
                                          heard_words=[[w, round(c, 3)] for w, c in
                                                       zip(utterance.heard.words, utterance.heard.confidences)],
                                          **({"ears": ears} if ears is not None else {}))
        return all_understood

    def answer(self, utterance, question: str, scene_time: float) -> None:
        """One of the person's answers to the robot's `question` about an unseen move (a `HeardUtterance` whose
        `understood` is the cell heard): audio on `/audio/user`, words and cell on the user's `/dialogue` turn."""
        from ncbot.speech.align import word_errors

        t, ears = self._reply(utterance, scene_time, count=False)
        record = self.record
        record.cell_answers += 1
        record.cell_answer_words += len(utterance.said.split())
        record.cell_answer_word_errors += word_errors(utterance.said.split(), utterance.heard.words)
        record.cell_answer_cpu_seconds.append(utterance.asr_cpu_s)
        if self.logger is not None:
            self.answers.append({"question": question, "said": utterance.said, "heard": utterance.heard.text,
                                 "heard_words": [[w, round(c, 3)] for w, c in
                                                 zip(utterance.heard.words, utterance.heard.confidences)],
                                 "understood": utterance.understood, "snr_db": utterance.snr_db, "t": round(t, 4),
                                 **({"ears": ears} if ears is not None else {})})

    def flush(self) -> None:
        """Hand the utterances' notes to the logger before the step's /dialogue turns are written."""
        if self.logger is not None:
            for speaker, audio in self.notes.items():
                self.logger.note_dialogue(speaker, audio=audio)
            if self.answers:
                self.logger.note_dialogue("user", cell_answers=self.answers)
        self.notes, self.answers = {}, []
