"""The config layer: from Hydra's composed config and the command line to typed, checked settings.

``config`` turns a composed config into typed settings (its groups read by ``reader``, ``dynamics``
and ``demos``), ``problem_defaults`` gives each problem its own default dynamics, ``overrides``
parses a command-line override, ``compose_memo`` and ``hydra_internals`` compose configs (the latter
holds every use of Hydra's private API), and ``paths`` says where the configs are.
"""
