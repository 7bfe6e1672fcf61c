"""One module per Hydra job (generate, fit, ...), each a plain ``main(cfg)`` plus its Hydra entry point."""
