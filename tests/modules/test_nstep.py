"""n-step returns (TorchRL's MultiStepTransform as `ncbot.modules.replay.transitions` configures it): exact against a plain
per-step loop, across collector batch boundaries, with the done flags of the window's end; and a real run."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from ncbot.modules.replay.transitions import STEPS_KEY, make_multistep

torch.set_num_threads(1)


def _batch(rows: int, steps: int, start: int, generator: torch.Generator) -> TensorDict:
    """Fake collector batch: observation = global step id, random learning rewards and episode ends."""
    ids = torch.arange(start, start + steps).expand(rows, steps) + 1000 * torch.arange(rows).unsqueeze(1)
    done = torch.rand(rows, steps, 1, generator=generator) < 0.3
    terminated = done & (torch.rand(rows, steps, 1, generator=generator) < 0.8)
    return TensorDict({
        "observation": ids.float().unsqueeze(-1),
        "action": ids,
        "next": {"observation": (ids + 1).float().unsqueeze(-1),
                 "learning_reward": torch.randn(rows, steps, 1, generator=generator),
                 "done": done, "terminated": terminated, "truncated": done & ~terminated},
    }, batch_size=[rows, steps])


def _reference(steps: TensorDict, n: int, gamma: float) -> dict[int, tuple[float, float, bool, bool, int]]:
    """Per start id: (n-step reward, next observation, done, terminated, window length), by a plain loop."""
    out = {}
    for row in range(steps.shape[0]):
        length = steps.shape[1]
        for t in range(length - n + 1):
            total, end = 0.0, t + n - 1
            for k in range(n):
                total += gamma ** k * float(steps["next", "learning_reward"][row, t + k])
                if bool(steps["next", "done"][row, t + k]):
                    end = t + k
                    break
            out[int(steps["action"][row, t])] = (total, float(steps["next", "observation"][row, end]),
                                                 bool(steps["next", "done"][row, end]),
                                                 bool(steps["next", "terminated"][row, end]), end - t + 1)
    return out


@pytest.mark.parametrize("n", [2, 3, 5])
def test_matches_a_plain_loop_across_batches(n: int) -> None:
    generator = torch.Generator().manual_seed(n)
    batches = [_batch(4, 6, 6 * i, generator) for i in range(4)]
    multistep = make_multistep(n, 0.9)
    emitted = torch.cat([multistep.inv(b).reshape(-1) for b in batches])
    assert emitted.shape == (4 * 6 * 4 - 4 * n,)  # every step once, except the last n of each row, still waiting
    expected = _reference(torch.cat(batches, dim=1), n, 0.9)
    for i in range(emitted.shape[0]):
        reward, next_obs, done, terminated, length = expected[int(emitted["action"][i])]
        assert float(emitted["next", "learning_reward"][i]) == pytest.approx(reward, abs=1e-5)
        assert float(emitted["next", "observation"][i]) == next_obs
        assert bool(emitted["next", "done"][i]) == done and bool(emitted["next", "terminated"][i]) == terminated
        assert int(emitted[STEPS_KEY][i]) == length  # the loss bootstraps with gamma ** length
        assert float(emitted["observation"][i]) == float(emitted["action"][i])  # the start state is kept


def test_one_step_needs_no_transform_and_bad_arguments_are_one_line_errors() -> None:
    assert make_multistep(1, 0.9) is None
    with pytest.raises(ValueError, match="loss.n_step must be >= 1"):
        make_multistep(0, 0.9)
    with pytest.raises(ValueError, match="gamma"):
        make_multistep(3, 1.5)


def test_training_with_n_step_returns(tmp_path) -> None:
    """A real (tiny) run with loss.n_step=3 trains and differs from the one-step run."""
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train
    from tests.learning_helpers import write_tiny_config

    results = {}
    for n in (1, 3):
        (tmp_path / f"n{n}").mkdir()
        path = write_tiny_config(tmp_path / f"n{n}", loss={"n_step": n}, eval={"games": 16, "periodic_games": 16})
        results[n] = train(load_config(path), tmp_path / f"n{n}" / "run")
    assert results[3]["frames"] == results[1]["frames"]
    assert results[3]["history"][-1]["train_loss"] != results[1]["history"][-1]["train_loss"]
    (tmp_path / "bad").mkdir()
    with pytest.raises(ValueError, match="loss.n_step"):
        load_config(write_tiny_config(tmp_path / "bad", loss={"n_step": 0}))
