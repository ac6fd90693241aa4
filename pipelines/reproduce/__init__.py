"""`ncbot reproduce`: the paper's table grid, its parts (budget, dialogues, lengths, vision) and their reports."""
