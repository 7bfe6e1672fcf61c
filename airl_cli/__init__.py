"""airl: adversarial inverse reinforcement learning with changing dynamics (a command-line experiment runner)."""

__version__ = "0.1.0"
