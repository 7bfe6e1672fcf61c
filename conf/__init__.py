# Hydra configs of airl, shipped inside the package as ``airl_cli.conf`` (see pyproject.toml).
