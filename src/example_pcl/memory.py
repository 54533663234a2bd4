"""Tuning of the C library's allocator for a node that receives large messages at a high rate."""
import ctypes


def keep_freed_memory(keep_bytes: int = 256 << 20) -> bool:
    """Makes glibc's malloc reuse freed blocks of up to 32 MB instead of handing them back to the kernel.

    Every cloud passes through several fresh blocks of its size (rospy's read, the message's data,
    the writer's buffers). By default glibc unmaps or trims such blocks as soon as they are freed,
    and the next cloud faults them in again page by page: a bare rospy subscriber to the 30 Hz
    4.9 MB Kinect stream spent 12-14 ms of CPU per message, 5 ms with freed memory kept. Blocks
    up to 32 MB (glibc's most) then come from the heap, and up to ``keep_bytes`` of it stay
    mapped when free. Process-wide, so only for a node's own process. Returns False, changing
    nothing, where the C library has no mallopt (not glibc).
    """
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    # Both: fixing either one turns off glibc's adaptive thresholds, and a fixed trim threshold
    # alone leaves every block above 128 KB to mmap (worse than the default).
    return bool(mallopt(m_mmap_threshold, 32 << 20)) and bool(mallopt(m_trim_threshold, keep_bytes))
