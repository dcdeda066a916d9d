"""The parts of :mod:`attica_dev.mutate`, mutation testing of firmware/src (one module per job)."""
