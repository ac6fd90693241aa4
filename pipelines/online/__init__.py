"""Learning from play: after each game the robot updates its reader (`ncbot.vision.online`) and its play (the
agent's own learner on the game's logged transitions mixed with simulation), per person or pooled, in a folder a
crashed run resumes from. Used by `ncbot robot play --learn`, `ncbot robot serve --learn` and `ncbot learn LOGS`."""
