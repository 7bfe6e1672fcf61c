"""The kinds of experiment, one folder each (``fit``, ``alphas``, ``viano``); their registry is ``airl_cli.experiment_kinds``."""
