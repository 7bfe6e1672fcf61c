"""Numerical building blocks with no MDP in them: HiGHS set up quietly, BLAS threads, low-rank
products and zero-sum matrix games. The bottom of ``airl_cli.core``: imports nothing above it."""
