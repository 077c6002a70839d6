"""A SUMO worker process: ``python -m syncroad._worker``.

The package starts one per SUMO run (or one per core for a sweep), as the ``syncroad``
binary re-executes itself: libsumo allows one simulation per process and can crash it, so it
never runs inside the notebook's process. The loop is the Rust worker's, with libsumo imported
from this interpreter's environment. Never started by hand.
"""

import sys

from syncroad._syncroad import worker_main

if __name__ == "__main__":
    sys.exit(worker_main())
