"""What is replayed and how: collected batches into transitions, samplers, board-symmetry augmentation."""
