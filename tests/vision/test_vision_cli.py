"""`ncbot vision ...`: the JSON object of `--json` (docs/cli.md), one error line per unreadable image, exit codes."""
import json
import subprocess
import sys

import cv2
import numpy as np

from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.data.frames import make_frame


def _ncbot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", "vision", *args], capture_output=True, text=True)


def test_read_json_contract_and_exit_codes(tmp_path) -> None:
    frame = make_frame(3, TEST_SEED + 600)
    good = tmp_path / "board.png"
    cv2.imwrite(str(good), frame.image)
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((240, 320, 3), 50, np.uint8))
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"no image")
    out = _ncbot("read", str(good), str(blank), str(broken), str(tmp_path / "missing.png"), "--grid", "3", "--json")
    assert out.returncode == 2, out.stderr  # an image could not be read: named on stderr, the others still read
    images = json.loads(out.stdout)["images"]
    assert [image["image"] for image in images] == [str(good), str(blank), str(broken), str(tmp_path / "missing.png")]
    assert images[0]["cells"] == frame.board
    assert all("error" in image and "cells" not in image for image in images[1:])
    errors = out.stderr.strip().splitlines()
    assert len(errors) == 3 and all(line.startswith("ncbot: error: ") for line in errors)
    assert [str(blank) in errors[0], str(broken) in errors[1], "missing.png" in errors[2]] == [True] * 3
    one = _ncbot("read", str(good), "--json")
    assert one.returncode == 0 and json.loads(one.stdout) == {"images": [{"image": str(good), "cells": frame.board}]}
    bad_grid = _ncbot("read", str(good), "--grid", "4")
    assert bad_grid.returncode == 2 and "grid must be 3" in bad_grid.stderr and "Traceback" not in bad_grid.stderr


def test_classify_json(tmp_path) -> None:
    cells, labels = make_cells(3, TEST_SEED + 601)
    paths = []
    for i, cell in enumerate(cells):
        paths.append(tmp_path / f"c{i}.png")
        cv2.imwrite(str(paths[-1]), cv2.resize(cell, (64, 64)))  # any size is accepted
    out = _ncbot("classify", *map(str, paths), "--json")
    assert out.returncode == 0, out.stderr
    images = json.loads(out.stdout)["images"]
    names = ["nought", "cross", "nothing"]
    assert [image["label"] for image in images] == [names[i] for i in labels]
    assert all(len(image["scores"]) == 3 for image in images)


def test_generate_writes_labelled_images(tmp_path) -> None:
    out = _ncbot("generate", "cells", "--out", str(tmp_path), "--n", "4", "--noisy")
    assert out.returncode == 0, out.stderr
    records = [json.loads(line) for line in (tmp_path / "labels.jsonl").read_text().splitlines()]
    assert len(records) == 4 and all((tmp_path / r["image"]).is_file() for r in records)
    bad = _ncbot("generate", "pictures", "--out", str(tmp_path))
    assert bad.returncode == 2 and "kind must be" in bad.stderr


def test_recogniser_evaluation_command(tmp_path) -> None:
    out = _ncbot("eval", "--what", "recogniser", "--sequences", "1", "--sequences9", "1", "--seed-set", "tuning",
                 "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr
    rows = json.loads((tmp_path / "recogniser_tuning.json").read_text())
    assert [(r["grid"], r["styles"], r["sequences"]) for r in rows] == [
        (3, "pen", 1), (3, "sketch+hershey", 1), (9, "pen", 1), (9, "sketch+hershey", 1)]
    assert all(r["reported_from_hand_frame"] == 0 for r in rows) and (tmp_path / "recogniser_tuning.png").is_file()
    bad = _ncbot("eval", "--what", "recogniser", "--seed-set", "mine", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--seed-set" in bad.stderr and "Traceback" not in bad.stderr
