"""Reading one config group's values with their types and ranges checked, naming ``group.key``
in every error (one sentence, ``ConfigError``). ``airl_cli.settings.config`` builds the settings with it."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from omegaconf import DictConfig, OmegaConf

from airl_cli.errors import ConfigError

Cell = tuple[int, int]


class Reader:
    """Reads typed values from one config group, naming ``group.key`` in every error."""

    def __init__(self, node: Any, group: str):
        if not isinstance(node, Mapping):
            raise ConfigError(f"'{group}' must be a config group (a mapping of keys), got {node!r}")
        self.node, self.group = node, group

    def _name(self, key: str) -> str:
        return f"{self.group}.{key}" if self.group else key

    def raw(self, key: str, default: Any = ...) -> Any:
        if key not in self.node or self.node[key] is None:
            if default is ...:
                raise ConfigError(f"'{self._name(key)}' is missing")
            return default
        return self.node[key]

    def int(self, key: str, *, lo: int | None = None, hi: int | None = None, default: Any = ...) -> int:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"'{self._name(key)}' must be a whole number, got {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise ConfigError(f"'{self._name(key)}' must be {_range(lo, hi)}, got {value}")
        return value

    def float(self, key: str, *, lo: float | None = None, hi: float | None = None, default: Any = ..., open_lo: bool = False) -> float:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"'{self._name(key)}' must be a finite number, got {value!r}")
        value = float(value)
        too_low = lo is not None and (value <= lo if open_lo else value < lo)
        if too_low or (hi is not None and value > hi):
            raise ConfigError(f"'{self._name(key)}' must be {_range(lo, hi, open_lo)}, got {value:g}")
        return value

    def choice(self, key: str, options: tuple[str, ...], default: Any = ...) -> str:
        value = self.raw(key, default)
        if value not in options:
            raise ConfigError(f"'{self._name(key)}' must be one of {', '.join(options)}; got {value!r}")
        return value

    def floats(self, key: str, *, length: int | None = None) -> tuple[float, ...]:
        value = self.raw(key)
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
        ):
            raise ConfigError(f"'{self._name(key)}' must be a list of numbers, got {value!r}")
        if length is not None and len(value) != length:
            raise ConfigError(f"'{self._name(key)}' must have {length} numbers, got {len(value)}")
        return tuple(float(v) for v in value)

    def cell(self, key: str, value: Any, size: int) -> Cell:
        ok = (
            isinstance(value, (list, tuple))
            and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        )
        if not ok:
            raise ConfigError(f"'{self._name(key)}' must hold cells [row, col], got {value!r}")
        if not all(1 <= v <= size for v in value):
            raise ConfigError(f"'{self._name(key)}' has the cell {list(value)} outside the {size}x{size} grid (rows and columns count from 1)")
        return (int(value[0]), int(value[1]))

    def cells(self, key: str, size: int, value: Any = ...) -> tuple[Cell, ...]:
        value = self.raw(key) if value is ... else value
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"'{self._name(key)}' must be a list of cells [row, col], got {value!r}")
        return tuple(self.cell(key, v, size) for v in value)


def _range(lo: Any, hi: Any, open_lo: bool = False) -> str:
    if lo is not None and hi is not None:
        return f"> {lo} and <= {hi}" if open_lo else f"between {lo} and {hi}"
    if lo is not None:
        return f"> {lo}" if open_lo else f">= {lo}"
    return f"<= {hi}"


def plain(cfg: DictConfig | Mapping) -> dict:
    """The config as plain Python containers, interpolations resolved.

    Raises:
        ConfigError: an interpolation that does not resolve (``mdp.n_states=${oops}``), in one sentence.
    """
    if isinstance(cfg, DictConfig):
        from omegaconf.errors import InterpolationResolutionError

        try:
            return OmegaConf.to_container(cfg, resolve=True)  # type: ignore[return-value]
        except InterpolationResolutionError as err:
            raise ConfigError(f"{err.full_key or 'a setting'}: {str(err).splitlines()[0].rstrip('.')}: an interpolation ${{...}} must name a setting of the config") from None
    return dict(cfg)
