"""``ncbot train-value``: the value network of the Q-guided search, trained on search results (expert iteration).

Why: the search's leaves were scored by one random playout each (``ncbot.modules.search.value_net`` says what that cost). Here
plain UCT (``mcts:N``, random playouts) plays games against itself and, at every position it decides, its root
value (the visit-weighted score of the mover's moves) becomes the label of that position; a network trained on
those labels gives a leaf what N playouts would, in one forward pass.

Games: a random opening of 0-8 moves (so the positions spread), then UCT with ``simulations`` playouts choosing
15 % of its moves uniformly at random (positions off its own best line too). Every decided position is one
sample; whole games go to the validation split (10 %), so no position is judged beside its own game's
neighbours. Training: binary cross-entropy on the soft labels, Adam with a cosine schedule, each batch in one of
the eight board symmetries. Everything is drawn from ``seed``: same seed and settings, same network.

Outputs (``OUT/``): ``positions.pt`` (the labelled positions, reused when the command is run again with the same
settings, so an interrupted training resumes after its slow part), ``value.pt``, ``value.json`` and
``value.png`` (validation error per epoch).
"""
from __future__ import annotations

import json
import random
import time
from pathlib import Path
from typing import Any

import torch

from ncbot.envs.core import FREE_MOVE_CHOICES
from ncbot.envs.games import make_game
from ncbot.envs.opponents.bitboards import ONGOING
from ncbot.envs.opponents.mcts import DEFAULT_EXPLORATION
from ncbot.envs.opponents.search import UCT, RandomRollout, run_search
from ncbot.fileio.atomic import atomic_write_text
from ncbot.modules.search.value_net import VALUE_GAME, DEFAULT_HIDDEN, N_FEATURES, feature_symmetries, make_value_net, position_features, \
    value_checkpoint
from ncbot.pipelines.checkpoint import atomic_save

RANDOM_MOVE_SHARE = 0.15
MAX_OPENING = 8
VALIDATION_SHARE = 0.1


def labelled_games(free_move: str, positions: int, simulations: int, seed: int, progress: bool = True
                   ) -> list[list[tuple[bytes, float]]]:
    """Self-play games of UCT; per game, (features, UCT root value for the side to move) of each decided position.

    The features (all 0 or 1) are kept as one byte each: 120K positions as Python float lists took ~200 MB."""
    from ncbot.pipelines.progress import progress_bar

    engine = make_game(VALUE_GAME, free_move).search_engine()
    rng = random.Random(seed)
    rand = rng.random
    start = engine.from_board([0] * 81, 1, -1)
    games: list[list[tuple[bytes, float]]] = []
    count = 0
    with progress_bar(total=positions, desc="labelled positions", unit="pos", disable=not progress) as bar:
        while count < positions:
            pos, opening, ply, game = start, rng.randint(0, MAX_OPENING), 0, []
            while engine.result(pos) == ONGOING and count < positions:
                moves = engine.moves(pos)
                if ply >= opening:
                    policy = UCT(engine, DEFAULT_EXPLORATION)
                    root = policy.root(pos, moves)
                    run_search(root, simulations, rand, policy, RandomRollout(engine))
                    value = sum(c.value for c in root.children) / sum(c.visits for c in root.children)
                    game.append((bytes(map(int, position_features(pos))), value))
                    count += 1
                    bar.update(1)
                    move = policy.choose(root, rand) if rand() >= RANDOM_MOVE_SHARE else moves[int(rand() * len(moves))]
                else:
                    move = moves[int(rand() * len(moves))]
                pos, ply = engine.play(pos, move), ply + 1
            games.append(game)
    return games


def split_games(games: list[list[tuple[bytes, float]]], seed: int) -> tuple[torch.Tensor, ...]:
    """(x_train, y_train, x_val, y_val): whole games to validation, VALIDATION_SHARE of them."""
    order = list(range(len(games)))
    random.Random(seed).shuffle(order)
    n_val = max(1, round(len(games) * VALIDATION_SHARE)) if len(games) > 1 else 0
    parts = []
    for chosen in (order[n_val:], order[:n_val]):
        samples = [sample for g in chosen for sample in games[g]]
        rows = bytearray(b"".join(f for f, _ in samples))
        x = torch.frombuffer(rows, dtype=torch.uint8).float().reshape(-1, N_FEATURES) if rows else torch.zeros(0, N_FEATURES)
        y = torch.tensor([v for _, v in samples]).reshape(-1, 1)
        parts += [x, y]
    return tuple(parts)


def fit_value_net(x: torch.Tensor, y: torch.Tensor, x_val: torch.Tensor, y_val: torch.Tensor, hidden: list[int],
                  epochs: int, seed: int, batch: int = 256, lr: float = 1e-3) -> tuple[torch.nn.Sequential, list[dict]]:
    """Train on soft labels with random symmetries; the validation mean squared error of the score after each epoch."""
    torch.manual_seed(seed)
    rng = random.Random(seed)
    net = make_value_net(hidden)
    optimiser = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-5)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, max(1, epochs))
    loss_fn = torch.nn.BCEWithLogitsLoss()
    maps = feature_symmetries()
    history = []
    for epoch in range(epochs):
        net.train()
        order = torch.randperm(len(x))
        total = 0.0
        for start in range(0, len(x), batch):
            index = order[start:start + batch]
            loss = loss_fn(net(x[index][:, maps[rng.randrange(8)]]), y[index])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(index)
        schedule.step()
        net.eval()
        with torch.no_grad():
            val_mse = ((torch.sigmoid(net(x_val)) - y_val) ** 2).mean().item() if len(x_val) else float("nan")
        history.append({"epoch": epoch + 1, "train_bce": total / max(1, len(x)), "val_mse": val_mse})
    return net, history


def draw_value_curve(history: list[dict], baseline: float, path: Path) -> Path:
    """Validation error per epoch against the error of predicting the mean label (the labels' variance)."""
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ax.plot([h["epoch"] for h in history], [h["val_mse"] for h in history], marker="o", label="value network")
    ax.axhline(baseline, color="grey", linestyle="--", label="predict the mean label")
    ax.set_xlabel("epoch")
    ax.set_ylabel("validation MSE of the score")
    ax.set_ylim(bottom=0)
    ax.legend()
    ax.set_title("Ultimate value network: error on held-out games")
    return save_figure(fig, path)


def train_value(out: str, *, free_move: str = "anywhere", positions: int = 100_000, simulations: int = 300,
                hidden: list[int] | None = None, epochs: int = 20, seed: int = 0, progress: bool = True) -> dict[str, Any]:
    """Generate (or reuse) labelled positions, train the network, write value.pt / value.json / value.png."""
    if free_move not in FREE_MOVE_CHOICES:
        raise ValueError(f"--free-move must be one of {', '.join(FREE_MOVE_CHOICES)}, got {free_move!r}")
    for name, number, least in (("--positions", positions, 10), ("--simulations", simulations, 1), ("--epochs", epochs, 1)):
        if number < least:
            raise ValueError(f"{name} must be at least {least}, got {number}")
    hidden = list(hidden or DEFAULT_HIDDEN)
    if not hidden or min(hidden) < 1:
        raise ValueError(f"--hidden must be positive layer sizes such as 256,256, got {hidden}")
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    settings = {"free_move": free_move, "positions": positions, "simulations": simulations, "seed": seed}
    cache = folder / "positions.pt"
    began = time.process_time()
    data = None
    if cache.is_file():
        try:
            data = torch.load(cache, map_location="cpu", weights_only=True)
        except Exception:  # noqa: BLE001 - a torn or foreign file is simply regenerated
            data = None
        if not isinstance(data, dict) or data.get("settings") != settings:
            data = None
    if data is None:
        games = labelled_games(free_move, positions, simulations, seed, progress)
        x, y, x_val, y_val = split_games(games, seed)
        data = {"settings": settings, "x": x.to(torch.uint8), "y": y, "x_val": x_val.to(torch.uint8), "y_val": y_val,
                "games": len(games), "cpu_s": time.process_time() - began}
        atomic_save(data, cache)
    x, x_val = data["x"].float(), data["x_val"].float()
    y, y_val = data["y"], data["y_val"]
    fit_began = time.process_time()
    net, history = fit_value_net(x, y, x_val, y_val, hidden, epochs, seed)
    baseline = ((y_val - y.mean()) ** 2).mean().item()
    report = {**settings, "hidden": hidden, "epochs": epochs, "games": data["games"], "train_positions": len(x),
              "val_positions": len(x_val), "val_mse": history[-1]["val_mse"], "val_mse_of_mean_label": baseline,
              "labelling_cpu_s": round(float(data["cpu_s"]), 1), "training_cpu_s": round(time.process_time() - fit_began, 1),
              "history": history}
    atomic_save(value_checkpoint(net, hidden, free_move, {k: v for k, v in report.items() if k != "history"}),
                folder / "value.pt")
    atomic_write_text(json.dumps(report, indent=2) + "\n", folder / "value.json")
    draw_value_curve(history, baseline, folder / "value.png")
    return report
