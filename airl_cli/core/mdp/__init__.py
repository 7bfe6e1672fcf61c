"""One finite-horizon tabular MDP (thesis §2.1): its arrays and checks, sparse dynamics, backward
induction and state marginals, demonstrations, the scores of §7.2, and the problems of §7.2-7.3
(random MDP, grid, Objectworld, environments from tables). Imports only ``core.numerics``."""
