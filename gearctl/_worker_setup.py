"""Set-up of gearctl's local Dask workers (a Dask preload module).

Ctrl-C in a terminal sends SIGINT to the whole process group: the local cluster's worker processes too. Each then
printed a ``KeyboardInterrupt`` traceback on the shared stderr while the command itself ended with one line and exit
code 130 (a review). The workers ignore SIGINT: the command that started them cancels their tasks and closes them.
"""

from __future__ import annotations

import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:  # noqa: ARG001 (Dask's preload signature)
    """Ignore SIGINT in this worker process (where it can be set: from the main thread)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
