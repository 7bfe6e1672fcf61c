"""Learning a reward (thesis chapter 5): the learner-adversary game and its double oracle, the
certified minimiser of eq. 5.9, the gradient learner, the variants of the game, and the methods
compared with it (MCE IRL, robust MCE IRL, projection, MMP, BC). The top of ``airl_cli.core``."""
