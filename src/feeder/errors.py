"""User-facing errors: one line, naming the file or setting and what is wrong."""


class FeederError(Exception):
    """An input or setting problem the user can fix. The CLI prints it as one line and exits 2."""
