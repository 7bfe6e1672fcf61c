"""Thesis Figs. 2-3: every exact alpha-vector at one (t, s) of two random MDPs against modified PBVI's (§6.3.3)."""
