"""Training the controller's database: phase 1 sampling, phase 2 discovery, the parallel
training run."""
