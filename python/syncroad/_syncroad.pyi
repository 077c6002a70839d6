"""Type stubs of the extension module ``syncroad._syncroad`` (crates/syncroad-py)."""

from typing import List, Optional, Tuple

__all__ = ["__version__", "execute", "main", "validate_scenario", "worker_main"]
__version__: str

def main(argv: List[str]) -> int:
    """The ``syncroad`` CLI: ``argv[0]`` is the program name; returns the exit code."""

def worker_main() -> int:
    """The SUMO worker loop on this process's stdin/stdout (``python -m syncroad._worker``)."""

def execute(argv: List[str], capture: bool = True) -> Tuple[int, Optional[str], str]:
    """Runs a CLI command line; returns ``(exit_code, error, captured_stdout)``. Raises
    ``KeyboardInterrupt`` after Ctrl-C once the command stopped and wrote its rows."""

def validate_scenario(path: str) -> Optional[str]:
    """The CLI's error message for an invalid scenario file, ``None`` when it is valid."""
