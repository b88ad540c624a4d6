"""Errors that mean "the user's input is wrong": the CLI prints them and exits with code 2."""


class InputError(ValueError):
    """Invalid input: a message for the user, no traceback."""


class StoreError(InputError):
    """A problem with the output file or an unfinished run (exists, locked, from another scene, unwritable)."""
