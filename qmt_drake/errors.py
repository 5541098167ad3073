"""Errors that name the user's input and what would fix it."""


class QmtInputError(ValueError):
    """Bad user input (scenario, plan file, CLI argument). The message is one line that names the
    input and says how to fix it; the CLI prints it without a traceback and exits with code 2."""


class QmtSimulationError(RuntimeError):
    """A simulation that failed (diverged, left the model's validity); the message names the
    time it failed at."""


class QmtNoPlanError(QmtInputError):
    """Limits that no plan of the method meets, and no least-violating plan to give (e.g. a path that
    a limit breaks at rest, so no timing exists): the message names the binding limit. A QmtInputError
    (the scenario's limits are the input to relax); the CLI exits with code 3, as for a
    least-violating plan."""
