"""Peak resident memory of this process alone, for benchmarks that measure it in a fresh child process.

``getrusage(RUSAGE_SELF).ru_maxrss`` is not that on Linux: the kernel carries the larger of the old and new
address spaces' high-water marks across ``exec``, so a child started by a big parent reports at least the
parent's peak (a 100-frame and a 10,000-frame child of a 370 MiB parent both report 370 MiB).  ``VmHWM`` in
``/proc/self/status`` belongs to the address space made at ``exec`` and is the child's own.
"""

from __future__ import annotations

import resource
import sys

__all__ = ["peak_rss_bytes"]


def peak_rss_bytes() -> int:
    """This process's peak resident set size in bytes (``VmHWM`` on Linux, ``ru_maxrss`` elsewhere)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)  # bytes on macOS, KiB elsewhere
