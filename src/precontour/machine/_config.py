"""Checked reading of TOML tables: every value typed and bounded, unknown keys rejected.

Messages name the file, the table (dotted path) and the key, in the style of Klipper's
``config.getfloat(..., above=0.)``.
"""

from __future__ import annotations

import math
from typing import Any

from ..errors import MachineFileError


class ConfigTable:
    """A view of one TOML table that remembers which keys were read.

    Call :meth:`finish` after reading to reject keys nobody asked for (misspellings).
    """

    def __init__(self, data: dict[str, Any], source: str, path: str):
        if not isinstance(data, dict):
            raise MachineFileError(f"[{path}] must be a table, got {type(data).__name__}",
                                   source=source)
        self.data = data
        self.source = source
        self.path = path
        self._used: set[str] = set()

    def error(self, key: str | None, message: str) -> MachineFileError:
        table = f"[{self.path}]" if self.path else "top level"
        where = table if key is None else (f"{table} {key}" if self.path else key)
        return MachineFileError(f"{where}: {message}", source=self.source)

    def has(self, key: str) -> bool:
        return key in self.data

    def keys(self) -> list[str]:
        return list(self.data)

    def _get(self, key: str, default: Any) -> Any:
        self._used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.error(key, "missing key")
        return default

    def get_float(self, key: str, default: Any = None, *, above: float | None = None,
                  minval: float | None = None, maxval: float | None = None,
                  nonzero: bool = False, required: bool = True) -> float | None:
        value = self._get(key, _REQUIRED if required and default is None else default)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value!r}")
        if above is not None and not value > above:
            raise self.error(key, f"must be > {above:g}, got {value:g}")
        if minval is not None and value < minval:
            raise self.error(key, f"must be >= {minval:g}, got {value:g}")
        if maxval is not None and value > maxval:
            raise self.error(key, f"must be <= {maxval:g}, got {value:g}")
        if nonzero and value == 0.0:
            raise self.error(key, "must be nonzero")
        return value

    def get_float_list(self, key: str, *, min_length: int = 1) -> list[float]:
        """A required non-empty list of finite numbers."""
        value = self._get(key, _REQUIRED)
        if not isinstance(value, list) or len(value) < min_length:
            raise self.error(key, f"must be a list of at least {min_length} number(s), got {value!r}")
        out = []
        for item in value:
            if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
                raise self.error(key, f"must hold finite numbers, got {item!r}")
            out.append(float(item))
        return out

    def get_str(self, key: str, default: Any = None, *, choices: tuple[str, ...] | None = None
                ) -> str:
        value = self._get(key, _REQUIRED if default is None else default)
        if not isinstance(value, str):
            raise self.error(key, f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"unknown value {value!r}; choose one of {', '.join(choices)}")
        return value

    def get_table(self, key: str, *, required: bool = True) -> "ConfigTable | None":
        value = self._get(key, _REQUIRED if required else None)
        if value is None:
            return None
        return ConfigTable(value, self.source, f"{self.path}.{key}" if self.path else key)

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self._used]
        if unknown:
            raise self.error(unknown[0], "unknown key (misspelt?)")


class _Required:
    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        return "<required>"


_REQUIRED = _Required()
