"""Viano et al.'s GridWorld (NeurIPS 2021): every method scored in their metric (beyond the thesis)."""
