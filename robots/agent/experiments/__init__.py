"""Experiments that reproduce the paper's tables with the simulated robot."""
