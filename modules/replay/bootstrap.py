"""Which next-state actions the TD target maximises over (`loss.bootstrap`): all available ones or the greedy set.

Why: the proposed agent never plays outside its greedy set (A minus A_hat: a winning or threat-making move when
there is one, never a move that hands the user an immediate win), and epsilon explores only inside A. Actions
outside those sets are therefore (almost) never trained, yet `available` bootstraps from the max over ALL of
them, so untrained, over-estimated values leak into every target; bootstrapping over the greedy set brings the
learned Q-values of the moves the agent plays to their exact values (measured on 3x3 in docs/learning.md, "What
the TD target maximises over"). `greedy` is the Bellman target of the masked policy the agent actually follows
(the expectimax the docs compare with).

Mechanics: the mask the target maximises over is stored under its own key, ("next", "bootstrap_mask"), which
`CompetitiveDQNLoss` reads through `set_keys(bootstrap_mask="bootstrap_mask")`: a copy of the env's
("next", "action_mask") for `available`, the NEXT state's greedy mask (the agent's own mask rule applied to the
env's next look-ahead keys) for `greedy`. The two look-ahead keys are then dropped so the replay buffer stays
small; ("next", "action_mask") keeps the env's meaning.
"""
from __future__ import annotations

from tensordict import TensorDictBase

from ncbot.modules.policies.masks import lookahead_rule

BOOTSTRAP_CHOICES = ("available", "greedy")
NEXT_LOOKAHEAD_KEYS = (("next", "lookahead_reward"), ("next", "winning_actions"))
BOOTSTRAP_MASK_KEY = ("next", "bootstrap_mask")


def _check(bootstrap: str) -> None:
    if bootstrap not in BOOTSTRAP_CHOICES:
        raise ValueError(f"unknown loss.bootstrap {bootstrap!r}; expected one of {', '.join(BOOTSTRAP_CHOICES)}")


def bootstrap_keys(bootstrap: str) -> tuple[tuple[str, str], ...]:
    """Extra transition keys `set_bootstrap_mask` needs from the collected batch (none for `available`)."""
    _check(bootstrap)
    return NEXT_LOOKAHEAD_KEYS if bootstrap == "greedy" else ()


def set_bootstrap_mask(transitions: TensorDictBase, bootstrap: str, lookahead: str) -> TensorDictBase:
    """Write ("next", "bootstrap_mask"): the next state's available actions (`available`) or its greedy mask under
    the `lookahead` rule (`greedy`); the look-ahead keys `greedy` reads are dropped."""
    _check(bootstrap)
    if bootstrap == "available":
        return transitions.set(BOOTSTRAP_MASK_KEY, transitions.get(("next", "action_mask")))
    rule = lookahead_rule(lookahead)
    if getattr(rule, "needs_tensordict", False):
        raise ValueError(f"loss.bootstrap 'greedy' works with the one-step mask rules (none, variant, one_step), "
                         f"not {lookahead!r}")
    missing = [key for key in NEXT_LOOKAHEAD_KEYS if key not in transitions.keys(include_nested=True)]
    if missing:
        raise ValueError(f"loss.bootstrap 'greedy' needs the transitions' {missing} (add them to the selected keys)")
    _, greedy = rule(transitions.get(("next", "action_mask")), transitions.get(NEXT_LOOKAHEAD_KEYS[0]),
                     transitions.get(NEXT_LOOKAHEAD_KEYS[1]))
    transitions.set(BOOTSTRAP_MASK_KEY, greedy)
    return transitions.exclude(*NEXT_LOOKAHEAD_KEYS)
