"""ncbot robot_sim: a simulated Pepper (SAPIEN 3) that plays Noughts & Crosses at a table.

Modules, each with one job:
- `pepper_model`: Pepper's kinematic tree from primitives, written as `assets/pepper.urdf`;
- `render_system`: the one SAPIEN render system per process, and the "no Vulkan device" error;
- `scene`: floor, table, the textured game sheet, lights, the robot, its mouth camera, the human's arm;
- `conditions`: the field's conditions (lab, office, atrium, random, or a YAML of ranges) drawn per game
  from a seed; `dressing` puts them in the scene (lights, surfaces from `textures`, clutter, a bystander),
  `camera_post` does the camera's part (exposure, white balance, noise, blur, JPEG);
- `sheet`: the sheet's canvas (grid + hand-drawn marks from `vision`) uploaded as the texture;
- `ik`, `motion`: position IK for the pen, base driving, gestures, drawing a mark;
- `localise`: the sheet's pose on the table from a camera frame;
- `human`: the simulated person (opponent model, drawing with an occluding arm, waits, nudges);
- `speech`: template speech (espeak-ng optional); without a checkpoint the robot decides with
  `ncbot.modules.policies.masks.LookaheadOnlyPolicy` (the paper's look-ahead filter alone);
- `game_config`, `report`: what `ncbot robot play` can change, and its per-game records and JSON report;
- `play`: the closed loop (env + vision recogniser + simulator + MCAP logger), `ncbot robot play`.
Import the submodules you need; nothing heavy is imported here.
"""
