"""Runs: the paper's experiments, Gymnasium, discovery, sweeps, checkpoints, benchmarks."""
