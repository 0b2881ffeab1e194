"""``python -m packetloss_cvx`` and the ``packetloss-cvx`` console script (its entry point is
    [`main`][packetloss_cvx.cli.main] here).

SIGINT and SIGTERM are handled from this module's first lines: until ``main`` installs its own handler (which removes
temporary files and locks on the way out) nothing has been written, so the early handler only says one line and
exits 130 / 143, where Python would print a KeyboardInterrupt traceback from inside an import. Only the program
imports this module (the console script, ``-m``), so the library's own import changes no handler.
"""

import os
import signal
import sys


def stop_early(signum: int, frame: object) -> None:
    """Before ``main`` runs: one line, exit 128 + the signal, nothing to clean up."""
    os.write(2, f"packetloss-cvx: interrupted by {signal.Signals(signum).name}\n".encode())
    os._exit(128 + signum)


for _signum in (signal.SIGINT, signal.SIGTERM):
    signal.signal(_signum, stop_early)

from .cli import main  # noqa: E402  after the handlers: an import interrupted is one line, not a traceback

__all__ = ["main"]

if __name__ == "__main__":
    sys.exit(main())
