"""A whole 3x3 game played through the page by headless Chromium (Debian's chromium + chromium-driver, Selenium),
with a click on a taken cell and a reload mid-game; the robot learns every move through its camera."""
from __future__ import annotations

import pytest
from selenium.webdriver.common.by import By

from logs.summary import summarize_study
from pipelines.serve.chromium import board, click_cell, open_chromium, page_latencies, play_to_end, start_game, status, wait_for
from tests.serve_helpers import running_server

pytestmark = [pytest.mark.sapien, pytest.mark.slow]


def test_a_whole_game_through_the_page_with_a_taken_cell_and_a_reload(tmp_path):
    out = tmp_path / "study"
    with running_server(out, "--idle-seconds", "60") as url:
        driver = open_chromium()
        try:
            start_game(driver, url + "/")
            seen: dict[str, object] = {}

            def disturb(d, turn: int) -> None:
                if turn == 0:  # the robot opened: its cell is taken
                    d.find_element(By.CSS_SELECTOR, '[data-act="hello"]').click()  # logged with the game
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

            outcome = play_to_end(driver, on_turn=disturb)
            assert outcome in ("win", "loss", "draw")
            assert status(driver).endswith(outcome)
            assert driver.find_element(By.ID, "play-again").is_displayed()
            assert driver.find_element(By.ID, "robot-says").text
            assert seen.get("error") and seen.get("reloaded")
            assert page_latencies(driver), "the page timed no click-to-reply"
        finally:
            driver.quit()
        study = summarize_study(out)
    assert study["sessions"] == 1 and study["games"] == 1
    assert study["misrecognised_moves"] == 0 and study["unseen_moves"] == 0
    assert sum(study["outcomes"].values()) == 1 and study["outcomes"][outcome] == 1
    assert study["person_dialogue_acts_per_session"]["max"] == 1


def test_a_whole_ultimate_game_through_the_page(tmp_path):
    out = tmp_path / "study"
    with running_server(out, "--game", "ultimate", "--idle-seconds", "60") as url:
        driver = open_chromium()
        try:
            start_game(driver, url + "/", first="human")
            assert len(board(driver)) == 81

            def first_legal(cells: list[str]) -> int:  # the page highlights the small board the person must play in
                legal = driver.find_elements(By.CSS_SELECTOR, "[data-cell].legal")
                return int(legal[0].get_attribute("data-cell"))

            outcome = play_to_end(driver, choose=first_legal, timeout=600)
            assert status(driver).endswith(outcome) and outcome in ("win", "loss", "draw")
        finally:
            driver.quit()
        study = summarize_study(out)
    assert study["games"] == 1 and study["misrecognised_moves"] == 0 and study["unseen_moves"] == 0
