"""Errors that name the file, line and field at fault."""


class InputError(ValueError):
    """A malformed input file: ``FILE:LINE: message`` (LINE omitted when unknown)."""

    def __init__(self, path, message, line=None, field=None):
        self.path, self.line, self.field = str(path), line, field
        where = self.path if line is None else f"{self.path}:{line}"
        what = message if field is None else f"field '{field}': {message}"
        super().__init__(f"{where}: {what}")


def read_toml(path, text: str | None = None) -> dict:
    """Parse a TOML file (or ``text`` standing for it); errors name the file."""
    import tomllib
    from pathlib import Path

    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8-sig")
        except UnicodeDecodeError as exc:
            raise InputError(path, f"not UTF-8 text: {exc.reason}") from None
        except OSError as exc:
            raise InputError(path, exc.strerror or str(exc)) from exc
    try:
        return tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, f"not valid TOML: {exc}") from exc
