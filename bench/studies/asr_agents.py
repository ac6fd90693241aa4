"""Do agents trained with the ASR channel model play differently from uniform ones?

    python bench/studies/asr_agents.py --agent uniform=RUN/checkpoint.pt --agent channel=RUN/checkpoint.pt \
        [--games 400] [--real-games 100] [--seed 0]

Each agent plays greedy test games (seats alternating, random opponent) while hearing the user three ways:
`uniform` (the words said at uniform random confidences: the uniform agent's training condition), `channel` (the
fitted channel model, babble at 10-30 dB: the channel agent's training condition) and `real` (the person's
replies spoken by the four flite voices at their normal rate, babble of the report talkers at 10-30 dB per
utterance, decoded by pocketsphinx: voices, talkers and noise seeds apart from the channel's fit). Per agent and
hearing: task success (win or draw), dialogue length (robot actions per game), how often the robot asks again
(a dialogue act equal to its previous act in the same game) and how often the reply was understood as said.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

SNR_DB = (10.0, 30.0)


class Understood:
    """Wraps an env hearing and counts the replies understood as the utterance said (silence not counted)."""

    def __init__(self, inner, game: str, dialogues: str) -> None:
        from ncbot.envs.dialogue import build_dialogue_model

        self.inner, self.said, self.ok = inner, 0, 0
        self.texts = build_dialogue_model(game, dialogues).utterance_texts

    def hear(self, utterance: torch.Tensor, generator: torch.Generator | None = None):
        columns, confidence, understood = self.inner.hear(utterance, generator)
        for said, got in zip(utterance.tolist(), understood.tolist()):
            if said < len(self.texts):
                self.said += 1
                self.ok += int(got >= 0 and self.texts[got] == self.texts[said])
        return columns, confidence, understood


@torch.no_grad()
def play(env, policy, games: int) -> dict[str, float]:
    """Greedy games on a (games,) batched env, each slot's first game counted."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    cells = env.cells
    td = env.reset()
    counting = torch.ones(games, dtype=torch.bool)
    success = torch.zeros(games, dtype=torch.bool)
    length = torch.zeros(games)
    repeats = dialogue_acts = 0
    previous = torch.full((games,), -1)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        while counting.any():
            td = policy(td)
            action = td["action"].reshape(games)
            talk = counting & (action >= cells)
            dialogue_acts += int(talk.sum())
            repeats += int((talk & (action == previous)).sum())
            previous = torch.where(counting, action, previous)
            td, root = env.step_and_maybe_reset(td)
            length += counting.float()
            done = td["next", "done"].reshape(games)
            ended = counting & done
            outcome = td["next", "outcome"].reshape(games)
            success |= ended & ((outcome == 1) | (outcome == 3))  # envs.core: 1 robot win, 3 draw
            counting &= ~done
            previous = torch.where(done, torch.full_like(previous, -1), previous)
            td = root
    return {"games": games, "task_success": round(float(success.float().mean()), 4),
            "dialogue_length": round(float(length.mean()), 3),
            "dialogue_length_se": round(float(length.std() / games ** 0.5), 3) if games > 1 else None,
            "ask_again_rate": round(repeats / max(dialogue_acts, 1), 4)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--agent", action="append", required=True, help="NAME=checkpoint.pt (repeat)")
    parser.add_argument("--games", type=int, default=400, help="games per agent with uniform / channel hearing")
    parser.add_argument("--real-games", type=int, default=100, help="games per agent heard by the real recogniser")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)

    from ncbot.envs.core import OUTCOME_NAMES
    from ncbot.envs.dialogue import build_dialogue_model
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.run_env import make_run_env, run_hearing
    from ncbot.speech.asr import Recogniser
    from ncbot.speech.fit import REPORT_BABBLE_VOICES, REPORT_VOICES, babble_texts
    from ncbot.speech.hearing import RecogniserHearing
    from ncbot.speech.roundtrip import babble_pool

    assert OUTCOME_NAMES[1] == "win" and OUTCOME_NAMES[3] == "draw", OUTCOME_NAMES
    recogniser = Recogniser()
    pool = babble_pool(babble_texts(), REPORT_BABBLE_VOICES)
    results = []
    for spec in args.agent:
        name, _, path = spec.partition("=")
        config, policy = load_agent(path)
        env_config = config.env.model_copy(update={"asr_snr_db": list(SNR_DB), "asr_noise": "babble"})
        for hearing in ("uniform", "channel", "real"):
            started = time.perf_counter()
            if hearing == "real":
                parts, understood = [], []
                per_voice = max(1, args.real_games // len(REPORT_VOICES))
                dialogue = build_dialogue_model(config.env.game, config.env.dialogues)
                for index, voice in enumerate(REPORT_VOICES):
                    recogniser.reset()
                    ears = RecogniserHearing(dialogue.utterance_texts, dialogue.words, recogniser, voice=voice,
                                             snr_db=SNR_DB, kind="babble", babble_pool=pool,
                                             seed=[args.seed, 152, index])
                    env = make_run_env(env_config, batch_size=per_voice, seed=args.seed + index, first="alternate",
                                       hearing=ears)
                    parts.append(play(env, policy, per_voice))
                    understood += [h.understood >= 0 and ears.texts[h.understood] == h.said for h in ears.log]
                row = {key: round(sum(p[key] * p["games"] for p in parts) / sum(p["games"] for p in parts), 4)
                       for key in ("task_success", "dialogue_length", "ask_again_rate")}
                row["dialogue_length_se"] = None  # pooled over voices: see each voice's games for spread
                row["games"] = sum(p["games"] for p in parts)
                row["understood_rate"] = round(sum(understood) / max(len(understood), 1), 4)
            else:
                env_config_h = env_config.model_copy(update={"asr": hearing})
                counter = None  # uniform hearing: the words said, understood as said
                if hearing == "channel":  # count what the channel model made of each reply
                    counter = Understood(run_hearing(env_config_h), config.env.game, config.env.dialogues)
                env = make_run_env(env_config_h, batch_size=args.games, seed=args.seed, first="alternate",
                                   hearing=counter)
                row = play(env, policy, args.games)
                row["understood_rate"] = 1.0 if counter is None else round(counter.ok / max(counter.said, 1), 4)
            row.update(agent=name, hearing=hearing, seconds=round(time.perf_counter() - started, 1))
            results.append(row)
            print(json.dumps(row), flush=True)
    print("| agent | hearing | games | task success | dialogue length (± s.e.) | asks again | replies understood |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        se = "" if r["dialogue_length_se"] is None else f" ± {r['dialogue_length_se']:.2f}"
        print(f"| {r['agent']} | {r['hearing']} | {r['games']} | {r['task_success']:.3f} | {r['dialogue_length']:.2f}{se} | "
              f"{r['ask_again_rate']:.3f} | {r['understood_rate']:.3f} |")


if __name__ == "__main__":
    main()
