"""A whole 3x3 game played through the page by headless Chromium (Debian's chromium + chromium-driver, Selenium),
with answers typed and pressed (a "no" that changes what the robot says next, text it cannot understand), a click
on a taken cell and a reload mid-game; the robot learns every move through its camera."""
from __future__ import annotations

import httpx
import pytest
from selenium.webdriver.common.by import By

from ncbot.logs.summary import summarize_study
from tests.serve.chromium import (
    answer_with_button, board, click_cell, enabled_acts, open_chromium, page_latencies, play_to_end, start_game, status,
    type_answer, wait_for,
)
from tests.serve.helpers import running_server

pytestmark = [pytest.mark.sapien, pytest.mark.slow]
PLAY_QUESTION = "Would you like to play a game?"
MOVE_LINE = "I take this one."


def _says(driver) -> tuple[int, str]:
    element = driver.find_element(By.ID, "robot-says")
    return int(element.get_attribute("data-seq")), element.text


def _answer(seen: dict):
    """The person: types at the first greeting text the robot cannot understand, types their name, says no to the
    first "shall we play?" (the robot must not start the game) and answers everything else cooperatively."""

    def answer(d, n: int) -> None:
        seq, says = _says(d)
        heard = lambda d: d.find_element(By.ID, "heard").text  # noqa: E731
        if n == 0:
            type_answer(d, "blorp zzyzx")
            seen["not_understood"] = wait_for(d, heard, timeout=30, what="what the robot heard")
        elif says.startswith("My name is Pepper") and "typed" not in seen:
            type_answer(d, "My name is Alice!")
            seen["typed"] = wait_for(d, heard, timeout=30, what="what the robot heard")
        elif says == PLAY_QUESTION and "after_no" not in seen:
            seen["acts"] = enabled_acts(d)
            answer_with_button(d, "no")
            seen["after_no"] = wait_for(d, lambda d: (s := _says(d))[0] > seq and s[1], timeout=60, what="the reply to no")
        else:
            answer_with_button(d)

    return answer


def test_a_whole_game_through_the_page_with_a_taken_cell_and_a_reload(tmp_path):
    out = tmp_path / "study"
    with running_server(out, "--idle-seconds", "60") as url:
        driver = open_chromium()
        try:
            start_game(driver, url + "/")
            seen: dict[str, object] = {}

            def disturb(d, turn: int) -> None:
                if turn == 0:  # the robot opened: its cell is taken
                    before = board(d)
                    taken = next(i for i, mark in enumerate(before) if mark)
                    click_cell(d, taken)
                    error = wait_for(d, lambda d: d.find_element(By.ID, "error").text, timeout=20, what="the error")
                    seen["error"] = error
                    assert "taken" in error
                    assert board(d) == before and status(d).startswith("Your turn")
                elif turn == 1:
                    before = board(d)
                    d.refresh()
                    wait_for(d, lambda d: status(d).startswith("Your turn") and board(d) == before, timeout=30,
                             what="the reloaded page to show the same game")
                    seen["reloaded"] = True

            outcome = play_to_end(driver, on_turn=disturb, answer=_answer(seen))
            assert outcome in ("win", "loss", "draw")
            assert status(driver).endswith(outcome)
            assert driver.find_element(By.ID, "play-again").is_displayed()
            assert driver.find_element(By.ID, "robot-says").text
            assert seen.get("error") and seen.get("reloaded")
            assert "did not understand" in seen["not_understood"]
            assert "understood: 'my name is sam'" in seen["typed"]
            assert seen["acts"] == ["yes", "no", "silence"]  # only answers that fit "shall we play?"
            assert seen["after_no"][1] not in (MOVE_LINE, "Yes, let's play!")  # "no" never starts the game
            assert page_latencies(driver), "the page timed no click-to-reply"
            voice = driver.execute_script("return window.ncbotAudio")  # espeak-ng is installed here: every line spoken
            assert voice and httpx.get(url + voice[0]).content[:4] == b"RIFF"
            driver.find_element(By.ID, "mute").click()
            assert driver.find_element(By.ID, "mute").text.startswith("Unmute")
            assert driver.execute_script("return localStorage.getItem('ncbot-muted')") == "1"
        finally:
            driver.quit()
        study = summarize_study(out)
    assert study["sessions"] == 1 and study["games"] == 1
    assert study["misrecognised_moves"] == 0 and study["unseen_moves"] == 0
    assert sum(study["outcomes"].values()) == 1 and study["outcomes"][outcome] == 1
    assert study["person_dialogue_acts_per_session"]["max"] >= 4  # typed x2, "no", and the cooperative answers


def _whole_game_by_the_person_first(tmp_path, game: str, check_page, choose=None, timeout: float = 300) -> list[str]:
    """Serve ``game``, open it in Chromium with the person first, let ``check_page(driver)`` check the page before
    the first move, play to the end (``choose(driver, cells)``: the person's cell, default the first free one) and
    check that the robot saw every move; returns the final board as the page shows it."""
    out = tmp_path / "study"
    with running_server(out, "--game", game, "--idle-seconds", "60") as url:
        driver = open_chromium()
        try:
            start_game(driver, url + "/", first="human")
            check_page(driver)
            pick = None if choose is None else (lambda cells: choose(driver, cells))
            outcome = play_to_end(driver, choose=pick, timeout=timeout)
            assert status(driver).endswith(outcome) and outcome in ("win", "loss", "draw")
            final = board(driver)
        finally:
            driver.quit()
        study = summarize_study(out)
    assert study["games"] == 1 and study["misrecognised_moves"] == 0 and study["unseen_moves"] == 0
    return final


def test_a_whole_ultimate_game_through_the_page(tmp_path):
    def first_legal(driver, cells: list[str]) -> int:  # the page highlights the small board the person must play in
        legal = driver.find_elements(By.CSS_SELECTOR, "[data-cell].legal")
        return int(legal[0].get_attribute("data-cell"))

    def check_page(driver) -> None:
        assert len(board(driver)) == 81

    _whole_game_by_the_person_first(tmp_path, "ultimate", check_page, choose=first_legal, timeout=600)


def _labels(driver) -> list[str]:
    """The board's column and row labels as shown, once every one is displayed (just after the game starts some
    are not yet, and a hidden element's text reads as "")."""
    def shown(d) -> list[str] | None:
        labels = d.find_elements(By.CSS_SELECTOR, "#board .label")
        return [label.text for label in labels] if labels and all(label.is_displayed() for label in labels) else None

    return wait_for(driver, shown, timeout=30, what="the board's labels")


def test_a_whole_four_game_through_the_page(tmp_path):
    """A declared 4x4 board: sixteen squares named as the rules name them, the robot sees every move."""

    def check_page(driver) -> None:
        assert len(board(driver)) == 16
        assert _labels(driver) == ["", "a", "b", "c", "d", "1", "2", "3", "4"]
        assert driver.find_element(By.CSS_SELECTOR, '[data-cell="6"]').get_attribute("title") == "c2"
        assert "4 in a line wins" in driver.find_element(By.ID, "rules").get_attribute("textContent")

    final = _whole_game_by_the_person_first(tmp_path, "four", check_page)
    assert final.count("X") >= 4 and final.count("X") - final.count("O") in (0, 1)  # the person opened with x


def test_a_whole_connect_four_game_through_the_page_by_columns(tmp_path):
    """Gravity: the person clicks the TOP square of a column and the mark drops to its lowest empty square, on the
    page and on the sheet the robot reads."""
    from ncbot.envs.games import make_game

    rules = make_game("connect_four")
    clicked: list[int] = []

    def check_page(driver) -> None:
        assert len(board(driver)) == 42 and _labels(driver)[:8] == ["", "a", "b", "c", "d", "e", "f", "g"]

    def top_of_a_column(driver, cells: list[str]) -> int:  # the first column with room, clicked at its top (row 1)
        column = next(c for c in range(rules.cols) if cells[c] == "")
        clicked.append(column)
        return column

    final = _whole_game_by_the_person_first(tmp_path, "connect_four", check_page, choose=top_of_a_column)
    assert clicked and final[:rules.cols].count("") >= 1  # clicks on row 1 did not leave marks up there
    for cell, mark in enumerate(final):  # every mark rests on the bottom or on another mark
        below = cell + rules.cols
        assert not mark or below >= len(final) or final[below], (cell, final)
    assert final[(rules.rows - 1) * rules.cols + clicked[0]] == "X"  # the first click dropped to the bottom row


def test_the_person_touches_the_robots_tablet_when_its_camera_misses_a_move(tmp_path):
    """`--moves tablet`: the robot's camera never confirms a move, so after every mark the person draws the robot
    asks for a touch on its chest tablet (the page's board); a touch on a cell taken on the robot's board is
    refused, the right touch settles the move, and the robot's belief ends equal to the true board."""
    from ncbot.logs import LogReader
    from ncbot.robot_sim.where import ASK_TABLET
    from tests.serve.chromium import TABLET, touch_tablet

    out, seen = tmp_path / "study", {}

    def tablet(driver, cell: int) -> None:
        assert driver.find_element(By.ID, "robot-says").text == ASK_TABLET
        if "refused" not in seen:  # first, a cell the robot's own mark holds (the robot opened: it plays x)
            taken = next(i for i, mark in enumerate(board(driver)) if mark == "X")
            click_cell(driver, taken)
            seen["refused"] = wait_for(driver, lambda d: d.find_element(By.ID, "error").text, timeout=20, what="the error")
            assert status(driver).startswith(TABLET)
            assert "tablet" in driver.find_element(By.ID, "board").get_attribute("class")
        touch_tablet(driver, cell)
        seen["touches"] = seen.get("touches", 0) + 1

    with running_server(out, "--moves", "tablet", "--idle-seconds", "60", "--width", "160", "--height", "120") as url:
        driver = open_chromium()
        try:
            start_game(driver, url + "/", first="robot")
            outcome = play_to_end(driver, tablet=tablet)
            assert outcome in ("win", "loss", "draw")
        finally:
            driver.quit()
        study = summarize_study(out)
    assert "already taken on the robot's board" in seen["refused"]
    assert study["games"] == 1 and study["misrecognised_moves"] == 0 and study["unseen_moves"] == seen["touches"] >= 2
    reader = LogReader(next(out.glob("session-*")))
    episode = [m.data for m in reader.messages(["/episode"])][-1]
    boards = [m.data for m in reader.messages(["/board"])]
    assert boards[-1]["cells"] == episode["extra"]["true_boards"][-1]
