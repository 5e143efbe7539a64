"""The detector process's memory allocator settings (a process-wide tuning, applied at start-up)."""

from __future__ import annotations

import ctypes

__all__ = ["keep_freed_memory"]

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters


def keep_freed_memory() -> bool:
    """Let glibc's malloc keep the memory a frame frees for the next frame, instead of handing it
    back to the kernel and faulting it in again.

    A detector allocates and frees several MB of temporaries per frame (the depth backend's
    images, points and cell tables). With glibc's defaults, blocks above its adaptive mmap
    threshold and a heap top past its trim threshold go back to the kernel: on the 2-vCPU VM the
    depth backend then took 300 to 1,100 page faults a frame, 0.5-3 ms of a 10 ms frame at
    640x480, none with these settings (mmap only from 32 MiB, trim from 256 MiB). Returns whether
    they applied (glibc only; elsewhere nothing changes)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, 32 << 20)) and bool(mallopt(_M_TRIM_THRESHOLD, 256 << 20))
