"""ncbot: robot_sim."""
