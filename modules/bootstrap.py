"""Which next-state actions the TD target maximises over (`loss.bootstrap`): all available ones or the greedy set.

Why: the proposed agent never plays outside its greedy set (A minus A_hat: a winning or threat-making move when
there is one, never a move that hands the user an immediate win), and epsilon explores only inside A. Actions
outside those sets are therefore (almost) never trained, yet `available` bootstraps from the max over ALL of
them, so untrained, over-estimated values leak into every target. Measured on 3x3 (seed 0, 300K frames,
loss_reward -20): the learned Q of the corner reply to an edge opening was 0.36 above its exact value and the
agent lost 0.48 % of the robot-second games exactly; bootstrapping over the greedy set puts the same Q within
0.01 of exact and the exact loss at 0.07 % (docs/learning.md). `greedy` is the Bellman target of the masked
policy the agent actually follows (the expectimax the docs compare with).

Mechanics: the greedy mask of the NEXT state is computed from the env's next look-ahead keys with the agent's
own mask rule and stored in place of ("next", "action_mask"), which is what `CompetitiveDQNLoss` maximises
over; the two look-ahead keys are then dropped so the replay buffer stays as small as before.
"""
from __future__ import annotations

from tensordict import TensorDictBase

from modules.masks import lookahead_rule

BOOTSTRAP_CHOICES = ("available", "greedy")
NEXT_LOOKAHEAD_KEYS = (("next", "lookahead_reward"), ("next", "winning_actions"))


def _check(bootstrap: str) -> None:
    if bootstrap not in BOOTSTRAP_CHOICES:
        raise ValueError(f"unknown loss.bootstrap {bootstrap!r}; expected one of {', '.join(BOOTSTRAP_CHOICES)}")


def bootstrap_keys(bootstrap: str) -> tuple[tuple[str, str], ...]:
    """Extra transition keys `set_bootstrap_mask` needs from the collected batch (none for `available`)."""
    _check(bootstrap)
    return NEXT_LOOKAHEAD_KEYS if bootstrap == "greedy" else ()


def set_bootstrap_mask(transitions: TensorDictBase, bootstrap: str, lookahead: str) -> TensorDictBase:
    """With `greedy`, ("next", "action_mask") becomes the next state's greedy mask under the `lookahead` rule;
    `available` returns the transitions unchanged."""
    _check(bootstrap)
    if bootstrap == "available":
        return transitions
    rule = lookahead_rule(lookahead)
    if getattr(rule, "needs_tensordict", False):
        raise ValueError(f"loss.bootstrap 'greedy' works with the one-step mask rules (none, variant, one_step), "
                         f"not {lookahead!r}")
    missing = [key for key in NEXT_LOOKAHEAD_KEYS if key not in transitions.keys(include_nested=True)]
    if missing:
        raise ValueError(f"loss.bootstrap 'greedy' needs the transitions' {missing} (add them to the selected keys)")
    _, greedy = rule(transitions.get(("next", "action_mask")), transitions.get(NEXT_LOOKAHEAD_KEYS[0]),
                     transitions.get(NEXT_LOOKAHEAD_KEYS[1]))
    transitions.set(("next", "action_mask"), greedy)
    return transitions.exclude(*NEXT_LOOKAHEAD_KEYS)
