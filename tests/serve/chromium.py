"""Drive the serve page in headless Chromium (Debian's `chromium` + `chromium-driver`, through Selenium).

Why here and not only in tests: the same driver plays the CI game, takes the screenshots in docs/browser.md and
measures the one-player click-to-reply latency on the page itself (`window.ncbotLatencies`, timed in the page).

    python -m tests.serve.chromium --url http://127.0.0.1:8000 --games 3 --screenshots docs/browser
"""
from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path
from typing import Any

from ncbot.pipelines.serve.answers import PREFERRED_ACTS
from ncbot.pipelines.serve.latency import latency_stats

OUTCOMES = ("win", "loss", "draw")
ANSWERING = "Answer the robot"
TABLET = "Touch the robot's tablet"


def open_chromium(width: int = 1100, height: int = 900):
    """A headless Chromium WebDriver on the Debian binaries (no driver download)."""
    from selenium import webdriver

    binary = shutil.which("chromium") or "/usr/bin/chromium"
    driver_path = shutil.which("chromedriver") or "/usr/bin/chromedriver"
    if not Path(binary).exists() or not Path(driver_path).exists():
        raise FileNotFoundError("chromium and chromium-driver are not installed; run `bash scripts/setup.sh` as root")
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 f"--window-size={width},{height}", "--autoplay-policy=no-user-gesture-required"):
        options.add_argument(flag)
    return webdriver.Chrome(service=webdriver.ChromeService(executable_path=driver_path), options=options)


def wait_for(driver, condition, timeout: float = 120.0, what: str = "the page"):
    """Poll `condition(driver)` until truthy (returns it) or raise TimeoutError naming `what`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            value = condition(driver)
        except Exception:  # the element is being re-rendered; try again
            value = None
        if value:
            return value
        time.sleep(0.05)
    raise TimeoutError(f"timed out after {timeout} s waiting for {what}")


def status(driver) -> str:
    from selenium.webdriver.common.by import By

    return driver.find_element(By.ID, "status").text


def board(driver) -> list[str]:
    from selenium.webdriver.common.by import By

    return [cell.text for cell in driver.find_elements(By.CSS_SELECTOR, "[data-cell]")]


def click_cell(driver, cell: int) -> None:
    from selenium.webdriver.common.by import By

    driver.find_element(By.CSS_SELECTOR, f'[data-cell="{cell}"]').click()


def enabled_acts(driver) -> list[str]:
    """The answer buttons the page enables now (`data-act`)."""
    from selenium.webdriver.common.by import By

    return [b.get_attribute("data-act") for b in driver.find_elements(By.CSS_SELECTOR, "[data-act]") if b.is_enabled()]


def robot_reaction(driver) -> tuple[str, str]:
    """What changes once the robot has taken an answer: the sequence number of its latest line and what it heard."""
    from selenium.webdriver.common.by import By

    return driver.find_element(By.ID, "robot-says").get_attribute("data-seq"), driver.find_element(By.ID, "heard").text


def wait_answer_taken(driver, before: tuple[str, str], what: str) -> None:
    """Wait until the robot took an answer given when the page showed `before` (`robot_reaction`).

    Why not only "the status left 'Answer the robot'": an answer the robot does not understand makes it ask again
    at once, and the page can go from one answer window to the next between two polls; the robot's new line or
    what it heard changes either way."""
    wait_for(driver, lambda d: not status(d).startswith(ANSWERING) or robot_reaction(d) != before, timeout=30,
             what=what)


def answer_with_button(driver, act: str | None = None) -> str:
    """Press `act` (default: the first enabled of PREFERRED_ACTS) and wait until the robot took it."""
    from selenium.webdriver.common.by import By

    act = act or next(a for a in PREFERRED_ACTS if a in enabled_acts(driver))
    before = robot_reaction(driver)
    driver.find_element(By.CSS_SELECTOR, f'[data-act="{act}"]').click()
    wait_answer_taken(driver, before, "the answer to be taken")
    return act


def type_answer(driver, text: str) -> None:
    """Type `text` in the answer box, press Say and wait until the robot took it."""
    from selenium.webdriver.common.by import By

    before = robot_reaction(driver)
    box = driver.find_element(By.ID, "say-text")
    box.send_keys(text)
    driver.find_element(By.ID, "say-button").click()
    wait_answer_taken(driver, before, "the typed answer to be taken")


def start_game(driver, url: str, first: str = "robot", screenshot: Path | None = None) -> None:
    """Open the page, wait for the start screen (optionally photograph it) and press Start."""
    from selenium.webdriver.common.by import By

    driver.get(url)
    wait_for(driver, lambda d: d.find_element(By.ID, "start-button").is_displayed(), what="the start screen")
    wait_for(driver, lambda d: d.execute_script("return !!ws && ws.readyState === 1"), what="the websocket")
    if screenshot is not None:
        driver.save_screenshot(str(screenshot))
    driver.find_element(By.CSS_SELECTOR, f'[data-first="{first}"]').click()
    driver.find_element(By.ID, "start-button").click()


def touch_tablet(driver, cell: int) -> None:
    """Touch `cell` on the robot's tablet (the page's board while the robot asks) and wait until it is taken."""
    click_cell(driver, cell)
    wait_for(driver, lambda d: not status(d).startswith(TABLET), timeout=30, what="the touch to be taken")


def play_to_end(driver, choose=None, on_turn=None, answer=None, tablet=None, timeout: float = 300.0) -> str:
    """Click a cell on every 'Your turn' and answer the robot whenever it waits for an answer, until the status
    ends with an outcome; returns it (the person's side).

    `choose(board) -> cell` picks the cell (default: the first free one); `on_turn(driver, turn)` runs before
    each click (tests use it to click a taken cell or reload the page); `answer(driver, n)` answers the n-th
    time the robot waits (default: `answer_with_button`, a cooperative person); `tablet(driver, cell)` touches
    the robot's tablet when it asks after missing a move (default: `touch_tablet` on the cell just drawn).
    """
    deadline = time.monotonic() + timeout
    turn = answers = 0
    cell = -1
    while time.monotonic() < deadline:
        text = wait_for(driver, lambda d: (s := status(d)) and (s.startswith(("Your turn", ANSWERING, TABLET))
                                                                 or s.endswith(OUTCOMES)) and s,
                        timeout=max(1.0, deadline - time.monotonic()), what="your turn, an answer or the game's end")
        if text.endswith(OUTCOMES):
            return text.rsplit(" ", 1)[-1]
        if text.startswith(ANSWERING):
            (answer or (lambda d, n: answer_with_button(d)))(driver, answers)
            answers += 1
            continue
        if text.startswith(TABLET):
            (tablet or touch_tablet)(driver, cell)
            continue
        if on_turn is not None:
            on_turn(driver, turn)
            if not status(driver).startswith("Your turn"):
                continue
        cells = board(driver)
        cell = choose(cells) if choose else cells.index("")
        click_cell(driver, cell)
        turn += 1
        wait_for(driver, lambda d: not status(d).startswith("Your turn"), timeout=30, what="the click to be taken")
    raise TimeoutError(f"the game did not end within {timeout} s")


def page_latencies(driver) -> list[float]:
    """Click-to-reply times (s) the page measured: a click to the robot's next utterance shown."""
    return [float(x) for x in driver.execute_script("return window.ncbotLatencies")]


def main() -> None:
    from selenium.webdriver.common.by import By


    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000/")
    parser.add_argument("--games", type=int, default=3)
    parser.add_argument("--screenshots", type=Path, default=None, help="folder for start.png, answer.png, mid-game.png, end.png")
    args = parser.parse_args()
    shots = args.screenshots
    if shots is not None:
        shots.mkdir(parents=True, exist_ok=True)
    driver = open_chromium()
    outcomes: list[str] = []
    try:
        start_game(driver, args.url, screenshot=shots / "start.png" if shots else None)

        def photograph(d, turn: int) -> None:
            if shots is not None and turn == 1 and not outcomes:
                time.sleep(0.5)  # let the latest camera frame arrive
                d.save_screenshot(str(shots / "mid-game.png"))

        def answer(d, n: int) -> None:  # a cooperative person who types the answer to "shall we play?"
            from selenium.webdriver.common.by import By

            if d.find_element(By.ID, "robot-says").text.startswith("Would you like to play"):
                before = robot_reaction(d)
                box = d.find_element(By.ID, "say-text")
                box.send_keys("yes please")
                if shots is not None and not outcomes:
                    time.sleep(0.5)
                    d.save_screenshot(str(shots / "answer.png"))
                d.find_element(By.ID, "say-button").click()
                wait_answer_taken(d, before, "the typed answer")
            else:
                answer_with_button(d)

        for game in range(args.games):
            outcomes.append(play_to_end(driver, on_turn=photograph, answer=answer))
            wait_for(driver, lambda d: d.find_element(By.ID, "play-again").is_displayed(), what="the end screen")
            if shots is not None and game == 0:
                time.sleep(0.5)
                driver.save_screenshot(str(shots / "end.png"))
            if game + 1 < args.games:
                driver.find_element(By.ID, "play-again").click()
                wait_for(driver, lambda d: not d.find_element(By.ID, "play-again").is_displayed(), what="a new game")
        report: dict[str, Any] = {"games": args.games, "outcomes": outcomes,
                                  "click_to_reply_seconds": latency_stats(page_latencies(driver))}
    finally:
        driver.quit()
    print(json.dumps(report))


if __name__ == "__main__":
    main()
