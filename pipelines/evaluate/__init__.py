"""Evaluation of a trained agent: sampled games, the exact tree walk, the opponent ladder and terminal play."""
