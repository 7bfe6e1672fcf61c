"""The command line, split once: its overrides' parts (``GROUP=OPTION``, ``GROUP.KEY=VALUE``,
``+KEY=VALUE``, ``~KEY``) as ``Override``s, the whole as one ``CommandLine``.

The one module that splits an override string: every command that looks at its overrides before
Hydra does (``launch``, the jobs' checks, ``problem_defaults``, ``sweep``, ``io.run_folder``) reads
a ``CommandLine``; it imports nothing of airl.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

#: Keys an earlier version had, and the sentence that says what took their place (``settings.command_line.check_keys``).
RENAMED_KEYS = {
    "optim.bracket_tol": "'optim.bracket_tol' is now 'optim.tol': every fit closes the bracket on eq. 5.9's minimum, to a relative width of optim.tol (1e-3 by default)",
}


@dataclass(frozen=True)
class Override:
    """One command-line override, split once (``Override.of``).

    Attributes:
        text: as given (``+demos.n=10``).
        prefix: Hydra's ``+`` (add), ``++`` (force add) or ``~`` (delete), or "".
        key: what it sets or deletes, without the prefix (``demos.n``).
        sep: "=" where it sets a value, "" for ``~KEY``.
        value: the value as given ("" for ``~KEY``).
    """

    text: str
    prefix: str
    key: str
    sep: str
    value: str

    @classmethod
    def of(cls, text: str) -> Override:
        """``+demos.n=10`` -> Override("+demos.n=10", "+", "demos.n", "=", "10"); ``~seed`` -> (.., "~", "seed", "", "")."""
        left, sep, value = text.partition("=")
        key = left.lstrip("+~")
        return cls(text, left[: len(left) - len(key)], key, sep, value)

    @property
    def sets(self) -> bool:
        """Whether it sets a value (``KEY=VALUE``), not deletes one (``~KEY``)."""
        return bool(self.sep)

    @property
    def is_hydra(self) -> bool:
        """Whether it is Hydra's own (``hydra.KEY``, ``hydra/GROUP``), not the job's."""
        return self.key.startswith(("hydra.", "hydra/"))

    @property
    def unquoted(self) -> str:
        """The value without the quotes around it (a folder, a path)."""
        return self.value.strip("'\"")


@dataclass(frozen=True)
class CommandLine:
    """A command's overrides, each split once, in order: the one value every check before Hydra reads.

    Attributes:
        items: the overrides (``Override``).
        checked: whether airl's checks passed on them (``settings.command_line.checked``: group choices, keys,
            a problem's dynamics), so that a later step (the sweep's jobs) runs them no more.
    """

    items: tuple[Override, ...] = ()
    checked: bool = False

    @cached_property
    def chosen(self) -> dict[str, str]:
        """key -> value of every ``KEY=VALUE`` (the last one wins), read once."""
        return {o.key: o.value for o in self.items if o.sets}

    @cached_property
    def tasks(self) -> tuple[Override, ...]:
        """The overrides of the job's config (not Hydra's own), read once."""
        return tuple(o for o in self.items if not o.is_hydra)

    @classmethod
    def of(cls, overrides: CommandLine | Iterable[str]) -> CommandLine:
        """The command line of these overrides (a ``CommandLine`` is returned as it is)."""
        return overrides if isinstance(overrides, CommandLine) else cls(tuple(Override.of(o) for o in overrides))

    @property
    def overrides(self) -> list[str]:
        """The overrides as text, in order (what Hydra is given)."""
        return [o.text for o in self.items]

    def value(self, key: str) -> str | None:
        """The value the command line sets ``key`` to (the last), or None."""
        return self.chosen.get(key)

    def plus(self, *overrides: str) -> CommandLine:
        """This command line with ``overrides`` added after its own (airl's, checked or not checked as it is)."""
        return CommandLine(self.items + tuple(Override.of(o) for o in overrides), self.checked)

    def first(self, *overrides: str) -> CommandLine:
        """This command line with ``overrides`` put before its own (the command's own then win)."""
        return CommandLine(tuple(Override.of(o) for o in overrides) + self.items, self.checked)

    def input_values(self) -> list[str]:
        """The values the job's overrides set, unquoted (``io.run_folder`` looks for a run's inputs among them)."""
        return [o.unquoted for o in self.tasks if o.sets and o.unquoted]


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
        o = Override.of(item)
        key, sep, value = o.key, o.sep, o.value
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
