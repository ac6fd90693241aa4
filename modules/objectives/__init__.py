"""Training objectives as TorchRL losses, one per module, chosen by name (`loss.objective`)."""
