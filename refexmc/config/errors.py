"""The one error type for bad input: file, line, key path and what was expected."""

import difflib


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


def did_you_mean(word, candidates, cutoff=0.6):
    """``"did you mean 'x'?"`` for the closest of ``candidates`` to ``word`` (difflib), or ``""``."""
    guess = difflib.get_close_matches(str(word), list(candidates), n=1, cutoff=cutoff)
    return f"did you mean '{guess[0]}'?" if guess else ""
