"""The C heap of a process that runs the main job: memory it frees is kept
and reused, not handed back to the kernel to be faulted in and zeroed
again.

Why: the CPU's fine pass allocates and frees activations of tens to
hundreds of megabytes many times a second. glibc serves any block over
its mmap threshold (at most 32 MB) from a fresh mapping and unmaps it when
freed, so every new activation is faulted in and zeroed by the kernel: a
third of the CPU time of the job's network pass over ``kinect_paper``
went to zeroing pages (``perf``), and the fine pass ran 1.55–1.65× faster with mmap off and the
heap never trimmed (``benchmarks/bench_kernels.py write-over`` under
``MALLOC_MMAP_MAX_=0``; docs/reconstruction.md, "Cost"). The price: the process keeps
its peak heap until it exits.

The ``nrdepth`` command and :func:`~nrdepth.reconstruct_many`'s workers
call :func:`keep_freed_memory` for their own process; the Python API
leaves the caller's process as it is, unless the caller calls it.
"""

from __future__ import annotations

import ctypes
import sys

__all__ = ["keep_freed_memory"]

_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4  # glibc's mallopt parameters (malloc.h)


def keep_freed_memory() -> bool:
    """From now on, this process's C heap keeps what it frees (glibc's
    ``mallopt``: no block from mmap, the heap trimmed only past 2 GB free
    at its top), so that large buffers freed are reused rather than
    faulted in again (module docstring). True where it took effect; False
    where the C library is not glibc (macOS, Windows, musl), which is left
    as it is."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)  # the C library the process already runs
        libc.gnu_get_libc_version  # glibc only: musl's mallopt does nothing
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
