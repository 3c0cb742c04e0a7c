"""Shared validation helper for the FEM reference's frozen dataclasses."""

from __future__ import annotations

from .errors import ConfigError


def validated(obj, what: str) -> None:
    """Run ``obj._validate()``; a value that is not a number (text, None, ...) becomes a ConfigError."""
    try:
        obj._validate()
    except ConfigError:
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{what}: every dimension must be a number in SI units: {exc}") from None
