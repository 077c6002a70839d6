"""The ``syncroad`` console script: the CLI's main, with the same commands and exit codes."""

import signal
import sys

from syncroad import _syncroad


def main() -> int:
    """Runs ``syncroad ARGS…`` as the cargo-built binary does and returns its exit code."""
    # The CLI installs its own Ctrl-C, SIGTERM and SIGHUP handlers (stop, keep the rows,
    # exit 130/143/129); Python's SIGINT handler would also raise KeyboardInterrupt after
    # the command returned.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    argv = ["syncroad", *sys.argv[1:]]
    return _syncroad.main(argv)


if __name__ == "__main__":
    sys.exit(main())
