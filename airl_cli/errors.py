"""User-facing errors: each carries one sentence that the CLI prints before exiting non-zero."""


class AirlError(Exception):
    """Bad input from a user (a dataset file, a config value): reported without a traceback."""


class DatasetError(AirlError):
    """The dataset file is missing, malformed, or inconsistent (README, 'Bring your own MDP and demonstrations')."""


class ConfigError(AirlError):
    """A configuration value is out of range or inconsistent with another one."""
