"""airl's launcher for Hydra multiruns (``hydra/launcher=airl``); installed as ``hydra_plugins.airl_launcher``."""
