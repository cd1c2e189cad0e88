"""Resource limits: a request whose output would not fit is refused before any work starts.

Every run's memory follows from what was asked (samples x columns of its output); :func:`check_output_size`
compares that with a fixed cap and with the memory this machine has available, and refuses with the figure
and the option that changes it.
"""

from __future__ import annotations

import os

from .errors import InputError

__all__ = ["MAX_OUTPUT_BYTES", "available_memory", "check_output_size"]

#: Largest output array set a single run may hold [bytes], whatever the machine.
MAX_OUTPUT_BYTES = 4 * 1024**3


def available_memory() -> int | None:
    """Bytes of memory available to this process now (None where the platform does not say).

    On Linux the kernel's estimate ``MemAvailable`` (free memory plus the page cache and reclaimable memory it can
    give back): ``SC_AVPHYS_PAGES`` is the free memory alone, a few hundred MB on a machine that has read files for a
    while with gigabytes reclaimable, and refused designs and outputs that fit (half of it is the MPC's cap).
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    value, unit = line.split()[1:3]
                    return int(value) * (1024 if unit == "kB" else 1)
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def check_output_size(samples: int, columns: int, *, field: str, fix: str, what: str | None = None) -> None:
    """Refuse an output of ``samples`` rows and ``columns`` float columns that would not fit.

    Parameters
    ----------
    samples, columns : int
        Size of the output asked for.
    field : str
        The input that sets ``samples`` (``error.field``).
    fix : str
        What to change, in words (e.g. ``"a larger output interval --dt"``).
    what : str, optional
        What is sized, in words, for a footprint that is not an output's columns (e.g. ``"the closed loop"``).

    Raises
    ------
    InputError
        When ``samples x columns x 8`` bytes exceed :data:`MAX_OUTPUT_BYTES` or half the available memory.
    """
    need = 8 * samples * columns
    avail = available_memory()
    cap = MAX_OUTPUT_BYTES if avail is None else min(MAX_OUTPUT_BYTES, avail // 2)
    if need > cap:
        why = "half the memory available" if cap < MAX_OUTPUT_BYTES else "the cap"
        count = f"{samples:,}" if samples < 10**15 else f"{samples:.3g}"  # not 290 digits for --dt 1e-300
        size = (f"the output would hold {count} samples x {columns} columns = {need / 1e9:.3g} GB" if what is None
                else f"{what} would take about {need / 1e9:.3g} GB ({count} samples of {8 * columns} bytes)")
        raise InputError(f"{field}: {size}, more than the {cap / 1e9:.3g} GB this run may use ({why}); ask for fewer "
                         f"samples: {fix}", field=field)
