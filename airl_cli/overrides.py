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


def chosen_values(overrides: list[str]) -> dict[str, str]:
    """key -> value of every ``KEY=VALUE`` override (the last one wins), keys as ``split_override`` gives them."""
    chosen = {}
    for item in overrides:
        key, sep, value = split_override(item)
        if sep:
            chosen[key] = value
    return chosen
