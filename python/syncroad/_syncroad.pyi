"""Type stubs of the extension module ``syncroad._syncroad`` (crates/syncroad-py)."""

from typing import Any, Dict, List, Optional, Tuple, final

__all__ = [
    "Handoff",
    "__version__",
    "claim_libsumo",
    "execute",
    "main",
    "release_libsumo",
    "validate_scenario",
    "worker_main",
]
__version__: str

def main(argv: List[str]) -> int:
    """The ``syncroad`` CLI: ``argv[0]`` is the program name; returns the exit code."""

def worker_main() -> int:
    """The SUMO worker loop on this process's stdin/stdout (``python -m syncroad._worker``)."""

def execute(argv: List[str], capture: bool = True, here: bool = False) -> Tuple[int, Optional[str], str]:
    """Runs a CLI command line; returns ``(exit_code, error, captured_stdout)``. Raises
    ``KeyboardInterrupt`` after Ctrl-C once the command stopped and wrote its rows. ``here``:
    its SUMO run steps in this process, whose libsumo the caller claimed."""

def claim_libsumo() -> bool:
    """Takes this process's libsumo for one run stepped here; False while it is taken."""

def release_libsumo() -> None:
    """Gives back what ``claim_libsumo`` took."""

def validate_scenario(path: str) -> Optional[str]:
    """The CLI's error message for an invalid scenario file, ``None`` when it is valid."""

@final
class Handoff:
    """Where a run stepped in this process and its caller meet, one step at a time."""

    def __init__(self) -> None: ...
    def wait(self, timeout_s: Optional[float] = None) -> int:
        """1: an observation waits; 2: the run ended; 0: the time ran out."""
    def first(self) -> Optional[Dict[str, Any]]:
        """The fields sent once, with the first observation."""
    def take(self) -> bytes:
        """The waiting observation (float64: time, step, then the rows)."""
    def step(self, commands: bytes) -> int:
        """One command per vehicle (float64) for the run's next step, then ``wait()``."""
    def close(self, reason: str) -> None:
        """Stops the run at its next step, saying ``reason``."""
