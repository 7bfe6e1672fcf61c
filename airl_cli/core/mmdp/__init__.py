"""Several MDPs at once (thesis chapter 6): one deterministic history-dependent policy best over
all of them, by modified PBVI (``planner``), exactly (``exact``, tiny problems) or by the
multi-model MDP field's Markov heuristics (``baselines``); its policy graph and memory estimate.
Imports only ``core.numerics`` and ``core.mdp``."""
