"""Typed errors of the engine; the add-on maps them to ``self.report({'ERROR'}, ...)``."""


class WindgrassError(Exception):
    """Base class of every error the engine raises on purpose."""


class ParameterError(WindgrassError, ValueError):
    """A parameter is unknown, of the wrong type, not finite or out of range.

    ``key`` is the dotted name (``wind.speed``) so that callers (UI, CLI, TOML loader)
    can point at the offending field.
    """

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}" if key else message)
        self.key = key
        self.message = message


def shown(value, limit: int = 80) -> str:
    """``repr(value)`` for a message, cut to ``limit`` characters (a 3 MB string in a scene file
    is named, not printed whole)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 3]}... ({len(text):,} characters)"
