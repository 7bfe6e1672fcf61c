"""User-facing errors: each carries one sentence that the CLI prints before exiting non-zero.

Also what a stopped run is: a Ctrl-C (or a SIGTERM, see ``stop_on_sigterm``) and a results
folder that cannot be written are said in one sentence too, by the command that was running.
"""

from __future__ import annotations

import signal
from typing import Any, NoReturn


def error_line(sentence: object) -> str:
    """The one line every command prints for bad input or a stopped run, as rich markup:
    "error: SENTENCE", the sentence escaped (a value such as ``[0.1, 0.2]`` printed as it is) and
    in one style (``one_style``)."""
    from rich.markup import escape

    return f"[bold red]error:[/] {escape(one_style(str(sentence)))}"


def one_style(sentence: str) -> str:
    """A sentence after "error:" as every command words it: a plain first word in lower case ("The
    sweep folder ..." -> "the sweep folder ...", a name such as "OpenBLAS" kept) and no full stop."""
    text = sentence.strip()
    first = text.split(" ", 1)[0]
    if first[:1].isupper() and first[1:].isalpha() and first[1:].islower():
        text = text[0].lower() + text[1:]
    if text.endswith(".") and not text.endswith(".."):
        text = text[:-1]
    return text


def say_error(sentence: object, console: Any = None) -> None:
    """Print ``error_line(sentence)`` on standard error (``console``, or a new one), unwrapped."""
    if console is None:
        from rich.console import Console

        console = Console(stderr=True, highlight=False)
    console.print(error_line(sentence), soft_wrap=True)


def refuse(sentence: object, console: Any = None) -> NoReturn:
    """Stop a command on bad input: ``say_error(sentence, console)``, then exit with status 2."""
    import typer

    say_error(sentence, console)
    raise typer.Exit(2) from None


class AirlError(Exception):
    """Bad input from a user (a dataset file, a config value): reported without a traceback."""


class DatasetError(AirlError):
    """The dataset file is missing, malformed, or inconsistent (docs/own-problem.md, 'The dataset file')."""


class ConfigError(AirlError):
    """A configuration value is out of range or inconsistent with another one."""


class ResultsUnwritable(BaseException):  # noqa: N818 (named for what it says, like KeyboardInterrupt)
    """A results file could not be written (a full disk, a read-only folder) where Hydra or a sweep's
    worker would report an ``OSError`` with a traceback: a BaseException, like KeyboardInterrupt, so
    that it passes their error reports and reaches the command, which says it in one sentence.

    Args:
        reason: what went wrong, e.g. ``no space left on device: results/fit/x/.hydra/hydra.yaml``.
        folder: the run folder being written, if known.
    """

    def __init__(self, reason: str, folder: str | None = None) -> None:
        super().__init__(reason, folder)
        self.reason = reason
        self.folder = folder


#: The signal that stopped this process, for its exit status (128 + the signal's number).
_received = {"signal": int(signal.SIGINT)}


def interrupted(err: BaseException | None) -> bool:
    """Whether ``err`` is a Ctrl-C: a KeyboardInterrupt, or the SystemError that wraps one.

    A compiled (numba) kernel cannot be interrupted; Python raises the KeyboardInterrupt when the
    kernel returns, wrapped in ``SystemError: CPUDispatcher(...) returned a result with an
    exception set`` (possibly several times over).
    """
    while isinstance(err, SystemError):
        err = err.__cause__ or err.__context__
    return isinstance(err, KeyboardInterrupt)


def interrupt_status() -> int:
    """The exit status of a command stopped by a signal: 130 for Ctrl-C, 143 for SIGTERM."""
    return 128 + _received["signal"]


def stop_on_sigterm() -> None:
    """Make SIGTERM (``kill PID``) stop this process as Ctrl-C does, through KeyboardInterrupt, so
    that it cleans up (run folder, worker processes) instead of dying on the spot."""

    def stop(signum: int, _frame: object) -> None:
        _received["signal"] = signum
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)
