"""core.kinematics.memory: after keep_freed_memory, megabyte arrays come from the heap, not fresh mappings."""

from __future__ import annotations

import ctypes
import subprocess
import sys

import pytest

CODE = """
import ctypes, sys
import numpy as np
from core.kinematics.memory import keep_freed_memory

class Info(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Info
if sys.argv[1] == "tuned":
    assert keep_freed_memory()
before = libc.mallinfo2().hblkhd
a = np.ones(150_000)  # 1.2 MB, above glibc's initial 128 KiB mmap threshold
print(libc.mallinfo2().hblkhd - before)
"""


def mapped(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", CODE, mode], check=True, capture_output=True, text=True)
    return int(out.stdout)


@pytest.mark.skipif(not hasattr(ctypes.CDLL(None), "mallinfo2"), reason="needs glibc >= 2.33")
def test_megabyte_arrays_come_from_the_heap_once_tuned() -> None:
    assert mapped("default") >= 1_200_000  # glibc maps it afresh: its pages fault in when written
    assert mapped("tuned") == 0
