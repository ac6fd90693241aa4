"""Search with the learnt network: the Q-guided MCTS, its value network and the search teacher's labels."""
