"""Errors that name the file, line and field at fault."""


class InputError(ValueError):
    """A malformed input file: ``FILE:LINE: message`` (LINE omitted when unknown)."""

    def __init__(self, path, message, line=None, field=None):
        self.path, self.line, self.field = str(path), line, field
        where = self.path if line is None else f"{self.path}:{line}"
        what = message if field is None else f"field '{field}': {message}"
        super().__init__(f"{where}: {what}")
