"""The one error type for bad input: file, line, key path and what was expected."""


class ConfigError(Exception):
    """Bad input. ``str()`` gives ``file:line: key.path: message`` (the parts it has)."""

    def __init__(self, message, file=None, line=None, path=()):
        self.message = message
        self.file = file
        self.line = line
        self.path = tuple(path)
        super().__init__(str(self))

    def __str__(self):
        where = str(self.file) if self.file else ""  # no file (a command-line argument): no place to name
        if self.line is not None:
            where += f":{self.line}"
        key = ".".join(str(p) for p in self.path)
        return ": ".join(part for part in (where, key, self.message) if part)
