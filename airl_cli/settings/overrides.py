"""A command-line override's parts: ``GROUP=OPTION``, ``GROUP.KEY=VALUE``, ``+KEY=VALUE``, ``~KEY``.

Read by every command that looks at its overrides before Hydra does (``launch``, the jobs' checks,
``problem_defaults``, ``sweep``); it imports nothing of airl.
"""

from __future__ import annotations

#: Keys an earlier version had, and the sentence that says what took their place (``launch.check_keys``).
RENAMED_KEYS = {
    "optim.bracket_tol": "'optim.bracket_tol' is now 'optim.tol': every fit closes the bracket on eq. 5.9's minimum, to a relative width of optim.tol (1e-3 by default)",
}


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


def syntax_problem(args: list[str], command: str, options: list[str]) -> str | None:
    """One sentence on what is wrong with the overrides of ``airl COMMAND``, or None if nothing is.

    Hydra would answer each of these with its grammar's traceback (40 frames, exit 1):
    an option the command does not have (``--strcit``), an override without ``=``
    (``mdp.n_states 30``: the shell split it), one Hydra cannot parse (``mdp.n_states==30``), and
    a key set twice (``seed=1 seed=2``: Hydra keeps the last without a word).

    Args:
        args: the command line's extra arguments, in order (Hydra overrides).
        command: the command's name, for the sentence (``fit``).
        options: the command's own options (``--strict``), named in the sentence.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    parser = None
    seen: dict[str, str] = {}
    for item in args:
        if item.startswith("-"):
            return f"'{item}' is not an option of airl {command} (its options: {', '.join(options)}; see airl {command} --help)"
        key, sep, value = split_override(item)
        if not sep and not item.startswith("~"):
            return f"'{item}' sets nothing: an override is KEY=VALUE in one word, e.g. '{item}=VALUE' (no spaces around '='; quote a value with spaces)"
        parser = parser or OverridesParser.create()
        try:
            parser.parse_override(item)
        except HydraException as err:
            lines = [line.strip() for line in str(err).splitlines() if line.strip() and not line.strip().startswith(("See ", "^"))]
            detail = lines[-1].split(" expecting ")[0] if lines else ""
            if not value.isascii():  # Hydra's grammar reads unquoted values in ASCII only
                return f"cannot read the override '{item}': Hydra reads a value with characters beyond ASCII only in quotes; write {key}='{value}' (in the shell: \"{key}='{value}'\")"
            return f"cannot read the override '{item}' (Hydra's grammar: {detail}); write KEY=VALUE, quoting a value that holds '=', ',' or brackets"
        if key in seen:
            return f"'{key}' is set twice ({seen[key]!r} and {value!r}); give it once"
        seen[key] = value
    return None
