"""Errors that name the user's input and what would fix it."""


class QmtInputError(ValueError):
    """Bad user input (scenario, plan file, CLI argument). The message is one line that names the
    input and says how to fix it; the CLI prints it without a traceback and exits with code 2."""


class QmtSimulationError(RuntimeError):
    """A simulation that failed (diverged, left the model's validity); the message names the
    time it failed at."""
