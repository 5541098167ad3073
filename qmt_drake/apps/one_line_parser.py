"""An argparse parser whose errors are one line (QmtInputError, exit 2 through the CLI's main)
instead of argparse's usage block: `--seed abc` prints the flag, the value and the fix only."""

from __future__ import annotations

import argparse

from qmt_drake.errors import QmtInputError


class OneLineParser(argparse.ArgumentParser):
    """ArgumentParser that raises QmtInputError on a bad command line (its sub-parsers too)."""

    def error(self, message: str):
        raise QmtInputError(f"{self.prog}: {message} (see `{self.prog} --help`)")
