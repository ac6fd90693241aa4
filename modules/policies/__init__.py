"""How the agent acts: the look-ahead masks of the paper's agents and the greedy and epsilon-greedy policies."""
