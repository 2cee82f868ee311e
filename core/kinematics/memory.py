"""Keep freed heap memory for reuse instead of returning it to the system after every array.

With glibc's defaults, numpy temporaries of about 1 MB (a population of 200 designs x 360
samples of complex numbers) churn: the heap top is trimmed back to the system once more than
twice the (dynamic) mmap threshold is free, and the next allocation faults its pages in again,
zeroed by the kernel. In the predesign's similarity fit that was 1.7 ms of 2.9 ms per
population; a whole Stephenson-I design ran ~11 % faster with :func:`keep_freed_memory`.

Called by the entry points (``clm``, ``clm-studio``), the multi-start worker processes and the
benchmarks; a script that runs designs can call it too. It only changes where freed memory
goes: a process keeps up to ``trim`` bytes of free heap instead of returning them.
"""

from __future__ import annotations

import ctypes
import sys

# glibc's mallopt parameters (malloc.h).
M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3


def keep_freed_memory(mmap: int = 64 << 20, trim: int = 128 << 20, pad: int = 16 << 20) -> bool:
    """Set glibc's malloc thresholds (bytes): blocks below ``mmap`` come from the heap, up to ``trim``
    free bytes stay on it, and it grows ``pad`` bytes at a time. False where that is not possible
    (not glibc); nothing changes then."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all(mallopt(p, v) == 1 for p, v in ((M_MMAP_THRESHOLD, mmap), (M_TRIM_THRESHOLD, trim), (M_TOP_PAD, pad)))
