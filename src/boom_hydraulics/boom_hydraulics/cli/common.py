"""What the command-line tools share: arguments that fail as one line, and exit codes.

Exit codes: 0 done, 1 the work failed (a simulation, a file, a bag), 2 bad arguments or
configuration (ConfigError), 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from ..errors import BoomHydraulicsError, ConfigError


class RaisingParser(argparse.ArgumentParser):
    """argparse that raises ConfigError instead of exiting, so every error ends as one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(f"{self.prog}: {message}")


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that names each option's default once: added where the help text does not
    already say it, and left out where there is nothing to say (None, off, empty)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or not action.option_strings or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


def summary(doc: str | None) -> str:
    """The first line of a module docstring as plain text for ``--help`` (no reST markup)."""
    return (doc or "").strip().splitlines()[0].replace("``", "")


def run_main(prog: str, body: Callable[[], int]) -> int:
    """``body()``, with this package's errors printed as ``PROG: error: ...`` and turned into exit codes."""
    try:
        return body()
    except BoomHydraulicsError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, ConfigError) else 1
    except OSError as exc:
        print(f"{prog}: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
