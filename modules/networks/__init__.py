"""The agent's networks: the paper's Q-network (an MLP), its recurrent variant and the masked argmax over Q."""
