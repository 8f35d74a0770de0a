"""User-facing errors: the CLI prints them as one line and exits with code 2."""


class DiceSweepError(Exception):
    """An error caused by the user's input (a file, a key, a value), not by a bug."""


class ConfigError(DiceSweepError):
    """A config value is missing, unknown, of the wrong type or out of range.

    ``str(error)`` is one line: ``FILE: KEY: what is wrong (allowed: RANGE)``.
    """

    def __init__(self, file: str, key: str, message: str):
        self.file = str(file)
        self.key = key
        self.message = message
        super().__init__(f"{self.file}: {key}: {message}")
