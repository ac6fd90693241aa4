"""Where a run's networks live (`train.device`), and the few adapters between them and the CPU env.

The dialogue env is a CPU-bound, table-driven simulator and always runs on the CPU. The Q-network, its policies,
the loss, the target network, the optimiser and the replay storage go to the run's device. What crosses over:
the Collector moves each step's TensorDict to the policy's device and stores batches there; evaluation and the
guided search hand the network a TensorDict on its device and read the results back on the CPU (`on_device`);
checkpoints always hold CPU tensors (`to_cpu`), so they load on any machine.

Random generators: a generator lives where the tensors it draws are used. The board symmetries' generator (it
draws per-row indices that gather sampled batches) is made on the run's device; the others draw for the CPU and
stay there: the env's and its users' (`envs/`), the starting weights (`seeded_init`: the same on every device), the
search teacher's row picks and the guided search's seeds (the search runs on the CPU), the uniform and look-ahead
baselines. The replay sampler and epsilon-greedy draw from torch's default generator of their device.

Reproducibility is per device: on the CPU a seed gives bit-identical numbers to a run before this option existed;
on a GPU the same seed gives the same starting weights (drawn on the CPU, then moved) but its own random streams
(exploration, replay sampling) and sums in another order, so its numbers differ from the CPU's.
"""
from __future__ import annotations

from typing import Any, Callable

import torch
from torch import nn

CPU = torch.device("cpu")


def available_devices() -> str:
    """The devices this machine offers, as the one-line error names them."""
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if count == 0:
        built = "this torch is built without CUDA" if torch.version.cuda is None else "torch sees no CUDA GPU"
        return f"cpu only ({built}, torch {torch.__version__})"
    return "cpu, " + ", ".join(f"cuda:{index}" for index in range(count))


def resolve_device(spec: str) -> torch.device:
    """`train.device` -> a torch.device (a GPU always with its index): auto = the current CUDA GPU when torch sees
    one, else cpu. Asking for a GPU this machine does not have is a ValueError naming the key and what is available
    (the CLI's one line, exit code 2)."""
    if spec == "auto":
        return torch.device("cuda", torch.cuda.current_device()) if torch.cuda.is_available() else CPU
    if spec == "cpu":
        return CPU
    if not spec.startswith("cuda"):
        raise ValueError(f"config key 'train.device' must be auto, cpu, cuda or cuda:N, got {spec!r}")
    index = int(spec.partition(":")[2] or 0)
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if index >= count:
        raise ValueError(f"config key 'train.device' is {spec!r} but this machine has no such device; available: "
                         f"{available_devices()} (use train.device=cpu or auto)")
    # with its index: TorchRL's Collector compares devices with != and copies a policy whose parameters are on
    # "cuda:0" when told "cuda"; every part of the run names the same device
    return torch.device("cuda", index if ":" in spec else torch.cuda.current_device())


def module_device(module: Any) -> torch.device:
    """The device of a module's first parameter (or buffer); cpu for anything else."""
    declared = getattr(module, "policy_device", None)
    if declared is not None:
        return torch.device(declared)
    if isinstance(module, nn.Module):
        for tensor in module.parameters():
            return tensor.device
        for tensor in module.buffers():
            return tensor.device
    return CPU


def on_device(policy: Callable, device: torch.device | None = None) -> Callable:
    """`policy` as a function of CPU TensorDicts: on a GPU policy the TensorDict goes to its device and the result
    comes back to the CPU (the env's device); a CPU policy is returned as it is (the same calls, the same bits)."""
    device = module_device(policy) if device is None else torch.device(device)
    if device.type == "cpu":
        return policy

    def run(tensordict):
        return policy(tensordict.to(device)).to(CPU)

    return run


def to_cpu(value: Any) -> Any:
    """A checkpoint's state with every tensor on the CPU. Parts already on the CPU come back as the same objects
    (a CPU run saves exactly what it saved before); a dict with a moved tensor is copied with its `_metadata`."""
    if isinstance(value, torch.Tensor):
        return value if value.device.type == "cpu" else value.cpu()
    if isinstance(value, dict):
        moved = {key: to_cpu(item) for key, item in value.items()}
        if all(moved[key] is item for key, item in value.items()):
            return value
        copy = type(value)(moved) if type(value) is not dict else moved
        if hasattr(value, "_metadata"):  # nn.Module.state_dict's versions
            copy._metadata = value._metadata
        return copy
    if isinstance(value, (list, tuple)):
        moved = [to_cpu(item) for item in value]
        if all(new is old for new, old in zip(moved, value)):
            return value
        return moved if isinstance(value, list) else tuple(moved)
    if hasattr(value, "is_locked") and hasattr(value, "to"):  # a TensorDict
        on_cpu = all(leaf.device.type == "cpu" for leaf in value.values(True, True))
        return value if on_cpu else value.to(CPU)
    return value


def autocast_type(device: torch.device) -> str:
    """The `torch.autocast` device type of tensors on `device` ("cpu" or "cuda")."""
    return torch.device(device).type
