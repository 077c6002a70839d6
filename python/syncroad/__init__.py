"""syncroad: velocity-synchronization experiments on ring roads and platoons, natively and
in SUMO, from Python.

The functions run the commands of the ``syncroad`` CLI in-process (the same Rust code, the
same files and exit codes) and read their results back as Python objects::

    import syncroad
    r = syncroad.run("scenarios/sugiyama-ring.json")      # a SUMO run in a worker process
    r.verdict, r.metrics.sync.final_spread_mps, r.trajectories.to_pandas()
    syncroad.stability("scenarios/sugiyama-ring.json").verdict
    df = syncroad.sweep("sweeps/ring-gain-delay.native.json", out="out/sweep")

SUMO runs live in supervised worker processes (``python -m syncroad._worker``), as in the
CLI: libsumo allows one simulation per process and can crash it. A run the caller steps
(:class:`Simulation`, the Gymnasium environment) steps SUMO in the caller's process instead,
for speed, unless asked not to. Ctrl-C stops a command as in the CLI, keeps the rows
computed, and raises :class:`Interrupted`.
"""

from syncroad._api import check, compare, ifp, run, stability, sweep
from syncroad._errors import Interrupted, RecordError, RunError, ScenarioError, SyncroadError
from syncroad._run import Record, Run
from syncroad._scenario import Scenario
from syncroad._simulation import Simulation
from syncroad._syncroad import __version__

__all__ = [
    "Interrupted",
    "Record",
    "Run",
    "RecordError",
    "RunError",
    "Scenario",
    "ScenarioError",
    "Simulation",
    "SyncroadError",
    "__version__",
    "check",
    "compare",
    "ifp",
    "run",
    "stability",
    "sweep",
]
