"""What the command-line tools share: arguments that fail as one line, and exit codes.

Exit codes: 0 done, 1 the work failed (a simulation, a file), 2 bad arguments or
configuration (ConfigError), 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from .errors import BoomHydraulicsError, ConfigError


class RaisingParser(argparse.ArgumentParser):
    """argparse that raises ConfigError instead of exiting, so every error ends as one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(f"{self.prog}: {message}")


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
