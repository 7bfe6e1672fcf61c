"""A command-line override's parts: ``GROUP=OPTION``, ``GROUP.KEY=VALUE``, ``+KEY=VALUE``, ``~KEY``.

Read by every command that looks at its overrides before Hydra does (``launch``, the jobs' checks,
``problem_defaults``, ``sweep``); it imports nothing of airl.
"""

from __future__ import annotations


def split_override(item: str) -> tuple[str, str, str]:
    """(key, "=" or "", value) of a command-line override, the key without Hydra's leading ``+``
    (add) or ``~`` (delete): ``+demos.n=10`` -> ("demos.n", "=", "10"), ``~seed`` -> ("seed", "", "")."""
    key, sep, value = item.partition("=")
    return key.lstrip("+~"), sep, value


def override_key(item: str) -> str:
    """The key an override sets or deletes (``split_override``'s first part)."""
    return split_override(item)[0]
