"""The person's spoken answer to "where did you draw?" with the real engines (flite, pocketsphinx): the phrases,
what the answers' recognisers hear, the robot's questions (robot_sim.where) and each game's answer ears."""
from __future__ import annotations

import numpy as np
import pytest
import torch


@pytest.fixture(scope="module")
def ears_parts():
    from ncbot.speech.asr import Recogniser
    from ncbot.speech.cell_answers import answer_sentences, confirm_sentences
    from ncbot.speech.tts import SpeechCache

    return {3: Recogniser(answer_sentences(3)), 9: Recogniser(answer_sentences(9)),
            "confirm": Recogniser(confirm_sentences()), "cache": SpeechCache()}


def _ears(parts, grid=3, **kwargs):
    from ncbot.speech.cell_answers import AnswerEars

    return AnswerEars(grid, parts[grid], parts["confirm"], cache=parts["cache"], **kwargs)


def test_every_cell_has_one_phrase_and_only_exact_phrases_are_cells():
    from ncbot.speech.cell_answers import cell_of, cell_phrase, cell_phrases, words_of, yes_or_no

    for grid in (3, 9):
        phrases = cell_phrases(grid)
        assert len(phrases) == grid * grid and sorted(phrases.values()) == list(range(grid * grid))
        assert all(cell_of(words_of(cell_phrase(c, grid)), grid) == c for c in range(grid * grid))
    assert cell_phrase(0, 3) == "top left" and cell_phrase(4, 3) == "centre" and cell_phrase(8, 3) == "bottom right"
    assert cell_phrase(80, 9) == "bottom right square, bottom right cell" and cell_phrase(27, 9) == "middle left square, top left cell"
    for heard in ((), ("middle",), ("top", "left", "left"), ("left", "top")):
        assert cell_of(heard, 3) is None
    assert yes_or_no(("yes", "that", "is", "right")) is True and yes_or_no(("no", "that", "is", "wrong")) is False
    assert yes_or_no(("no", "that", "is", "right")) is None and yes_or_no(()) is None
    with pytest.raises(ValueError, match="cell must be"):
        cell_phrase(81, 9)


def test_each_cell_phrase_said_clean_is_heard_as_its_cell(ears_parts):
    from ncbot.speech.cell_answers import CONFIRM_NO, CONFIRM_YES, cell_phrase
    from ncbot.speech.tts import Voice

    ears = _ears(ears_parts, voice=Voice("flite", "rms"))
    assert [ears.hear_cell(cell_phrase(c, 3)).understood for c in range(9)] == list(range(9))
    assert [ears.hear_confirm(text).understood for text in (CONFIRM_YES, CONFIRM_NO)] == [1, 0]
    ultimate = _ears(ears_parts, grid=9, voice=Voice("flite", "awb"))
    assert [ultimate.hear_cell(cell_phrase(c, 9)).understood for c in (0, 40, 62)] == [0, 40, 62]
    assert all(h.snr_db is None and h.samples.dtype == np.int16 for h in ears.log)


def test_a_declared_grid_names_cells_by_row_and_column_and_hears_them():
    """The spoken form the declared rules parse ("row two, column three"), one phrase per cell, heard back."""
    from ncbot.envs.games import make_game
    from ncbot.speech.asr import Recogniser
    from ncbot.speech.cell_answers import AnswerEars, answer_sentences, cell_of, cell_phrase, cell_phrases, words_of
    from ncbot.speech.tts import Voice

    grid, rules = (6, 7), make_game("connect_four")
    phrases = cell_phrases(grid)
    assert len(phrases) == 42 and sorted(phrases.values()) == list(range(42))
    assert cell_phrase(0, grid) == "row one, column one" and cell_phrase(41, grid) == "row six, column seven"
    assert all(rules.parse_cell(cell_phrase(c, grid).replace(",", "")) == c for c in range(42))
    assert cell_of(words_of("column seven row six"), grid) is None  # only the exact phrase
    with pytest.raises(ValueError, match="cell must be 0-41 of a 6x7 grid"):
        cell_phrase(42, grid)
    ears = AnswerEars(grid, Recogniser(answer_sentences(grid)), voice=Voice("flite", "rms"))
    assert [ears.hear_cell(cell_phrase(c, grid)).understood for c in (3, 24, 38)] == [3, 24, 38]


def test_the_robot_asks_confirms_and_asks_again_at_most_three_times(ears_parts):
    from ncbot.robot_sim.where import ASK_AGAIN, ASK_WHERE, MAX_ASKS, ask_where

    said, heard = [], []
    legal = np.ones(9, bool)
    settled = ask_where(2, legal, _ears(ears_parts), said.append, lambda u, q: heard.append((u, q)))
    assert (settled.cell, settled.how, settled.asks, settled.confirmations) == (2, "confirmed", 1, 1)
    assert said == [ASK_WHERE, "top right, is that right?"] and [u.understood for u, _ in heard] == [2, 1]
    said.clear()
    legal[2] = False  # the robot believes the cell taken: the answer cannot settle the move
    settled = ask_where(2, legal, _ears(ears_parts), said.append, lambda u, q: None)
    assert settled.cell is None and settled.how is None and settled.asks == MAX_ASKS
    assert said == [ASK_WHERE] + [ASK_AGAIN] * (MAX_ASKS - 1)


def test_by_confidence_a_sure_cell_is_taken_a_doubtful_one_confirmed_and_the_rest_touched(ears_parts):
    """Clean answers are heard sure (posteriors near 1): with the accept threshold below that the cell is taken
    at once; above it, confirmed aloud; with every threshold out of reach, the tablet settles it after `asks`."""
    from ncbot.robot_sim.where import ASK_AGAIN, ASK_TABLET, ASK_WHERE, ask_where
    from ncbot.speech.answer_policy import AnswerThresholds

    legal, touched = np.ones(9, bool), []

    def tablet(free):
        touched.append(free.copy())
        return 7

    cases = ((AnswerThresholds(0.5, 0.3, 0.5), "accepted", [ASK_WHERE]),
             (AnswerThresholds(1.01, 0.3, 0.5), "confirmed", [ASK_WHERE, "bottom middle, is that right?"]),
             (AnswerThresholds(1.01, 1.01, 1.01, asks=2), "tablet", [ASK_WHERE, ASK_AGAIN, ASK_TABLET]))
    for thresholds, how, questions in cases:
        said = []
        settled = ask_where(7, legal, _ears(ears_parts), said.append, lambda u, q: None, thresholds, tablet)
        assert (settled.cell, settled.how) == (7, how) and said == questions
    assert len(touched) == 1 and touched[0].all()
    with pytest.raises(ValueError, match="needs the tablet"):
        ask_where(7, legal, _ears(ears_parts), said.append, lambda u, q: None, cases[0][0])


def test_answer_thresholds_are_saved_read_and_checked(tmp_path):
    from ncbot.speech.answer_policy import DEFAULT_THRESHOLDS, AnswerThresholds, phrase_confidence

    shipped = AnswerThresholds.load()
    assert shipped.confirm <= shipped.accept and "tuning" in shipped.meta["set"] and DEFAULT_THRESHOLDS.is_file()
    path = AnswerThresholds(0.8, 0.4, 0.7, 2, {"command": "x"}).save(tmp_path / "t.json")
    assert AnswerThresholds.load(path) == AnswerThresholds(0.8, 0.4, 0.7, 2)
    assert phrase_confidence([0.9, 0.4, 0.8]) == 0.4 and phrase_confidence([]) == 0.0
    for text, needle in (("{", "not a JSON file"), ('{"format": "other"}', "not an answer thresholds file"),
                         ('{"format": "ncbot-answer-thresholds/1", "accept": 0.5}', "need accept, confirm, yes")):
        (tmp_path / "bad.json").write_text(text)
        with pytest.raises(ValueError, match=needle):
            AnswerThresholds.load(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="confirm <= accept"):
        AnswerThresholds(0.4, 0.8, 0.5)
    with pytest.raises(FileNotFoundError, match="tune_answers"):
        AnswerThresholds.load(tmp_path / "none.json")


def test_replaying_recorded_answers_follows_the_robots_questions():
    """The tuning's replay of a setting asks, accepts, confirms and turns to the tablet as robot_sim.where does."""
    from ncbot.speech.answer_policy import AnswerThresholds
    from ncbot.speech.tune_answers import Answer, Replays, Trial, choose, evaluate

    sure_right, doubt_right_yes = Answer(4, True, 0.95, True, 0.9), Answer(4, True, 0.6, True, 0.9)
    sure_wrong_no_as_yes, nothing = Answer(5, True, 0.7, True, 0.8), Answer(-1, False, 0.0, None, 0.0)
    trials = [Trial(4, (sure_right, nothing, nothing)), Trial(4, (nothing, doubt_right_yes, nothing)),
              Trial(4, (sure_wrong_no_as_yes, sure_right, nothing)), Trial(4, (nothing, nothing, nothing))]
    settled, turns = Replays(trials).replay(AnswerThresholds(0.9, 0.5, 0.85, asks=2))
    # the third trial's wrong cell gets an unsure "yes" (0.8 < 0.85): asked again, the sure right cell is taken
    assert settled.tolist() == [4, 4, 4, -1] and turns.tolist() == [1, 3, 3, 3]
    # the wrong cell, heard at 0.7 and confirmed by a "yes" at 0.8: settled wrongly when the yes threshold is lower
    assert evaluate(Replays(trials), AnswerThresholds(0.9, 0.5, 0.75, asks=2))[0] == 1
    chosen, figures = choose(trials)
    assert evaluate(Replays(trials), chosen)[0] == 0 and figures["turns_per_move"] <= 2.0


def test_the_tuning_judges_a_one_question_setting_on_every_answer_not_only_the_first():
    """A wrong cell heard sure as the second answer never reaches a one-question setting in the recorded order;
    the rotations make it the first answer once, so a setting that would accept it is not chosen."""
    from ncbot.speech.answer_policy import AnswerThresholds
    from ncbot.speech.tune_answers import Answer, Replays, Trial, choose, evaluate, rotations, upper_bound_95

    right, wrong_sure = Answer(4, True, 0.95, False, 0.9), Answer(5, True, 0.8, False, 0.9)
    trials = [Trial(4, (right, wrong_sure, right))] + [Trial(4, (right, right, right))] * 3
    assert [t.answers[0] for t in rotations(trials[:1])] == [right, wrong_sure, right]
    one_question = AnswerThresholds(0.75, 0.5, 0.5, asks=1)
    assert evaluate(Replays(trials), one_question)[0] == 0
    assert evaluate(Replays(rotations(trials)), one_question)[0] == 1
    chosen, figures = choose(trials)
    assert chosen.accept > 0.8 + 0.05 and evaluate(Replays(rotations(trials)), chosen)[0] == 0
    assert figures["wrong_upper_95"] == pytest.approx(upper_bound_95(0, 4))
    # a "no" heard as a yes 0.6 sure after an answer heard as nothing (never confirmed in the replay) still bounds
    # the yes threshold: the confirmation's decoder errs the same whichever cell it is asked about
    from ncbot.speech.tune_answers import false_yeses

    unheard_no_as_yes = Answer(-1, False, 0.0, True, 0.6)
    with_false_yes = trials + [Trial(4, (right, unheard_no_as_yes, right))]
    assert false_yeses(Replays(with_false_yes), AnswerThresholds(0.9, 0.5, 0.6)) == 1
    assert false_yeses(Replays(with_false_yes), AnswerThresholds(0.9, 0.5, 0.65)) == 0
    chosen, figures = choose(with_false_yes)
    assert chosen.yes > 0.6 + 0.05 and figures["no_heard_as_yes"] == [0.6]
    # 0 wrong of 400 allows at most 0.75 % at 95 % (exact bound 1 - 0.05 ** (1 / 400))
    assert upper_bound_95(0, 400) == pytest.approx(0.007461, abs=1e-5)


def test_a_noisy_answer_flows_through_without_a_crash(ears_parts):
    from ncbot.robot_sim.where import ask_where
    from ncbot.speech.noise import NOISE_KINDS

    assert "white" in NOISE_KINDS
    outcomes = []
    for seed in range(3):
        ears = _ears(ears_parts, snr_db=(-5.0, 0.0), kind="white", seed=seed)
        legal = np.ones(9, bool)
        outcomes.append(ask_where(6, legal, ears, lambda text: None, lambda u, q: None).cell)
        assert all(-5.0 <= h.snr_db <= 0.0 and h.understood >= -1 for h in ears.log)
        assert len(ears.log) >= 2 and not np.array_equal(ears.log[0].samples, ears_parts["cache"].speak("bottom left", ears.voice)[0])
    assert all(o is None or 0 <= o < 9 for o in outcomes)


def test_each_game_hears_its_answers_apart_from_its_dialogue():
    from ncbot.robot_sim.conditions import load_conditions
    from ncbot.robot_sim.speech import GameSpeech

    speech = GameSpeech("standard", load_conditions("office"))
    said = torch.tensor([0, 3])
    plain = speech.hearing(5)
    plain.hear(said)
    hearing = speech.hearing(5)
    ears = speech.answer_ears(5, hearing)
    assert (ears.voice, ears.kind, ears.snr_db) == (hearing.voice, hearing.kind, hearing.snr_db)
    first = ears.hear_cell("top left")
    hearing.hear(said)  # the answers drew their noise from their own seed: the dialogue is heard as without them
    assert all(np.array_equal(a.samples, b.samples) and a.heard == b.heard for a, b in zip(plain.log, hearing.log))
    again = speech.answer_ears(5, speech.hearing(5)).hear_cell("top left")
    assert np.array_equal(first.samples, again.samples) and first.heard == again.heard and 20 <= first.snr_db <= 30
