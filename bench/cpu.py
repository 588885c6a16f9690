"""CPU seconds of this process and of every child it has or had (the warm SUMO process too).

``resource.RUSAGE_CHILDREN`` counts only children that have ended; the warm worker that
runs Step 1 (service.core.motion.poses.DRIVER) lives as long as this process, so its CPU time is
read from /proc while it runs. Both the generator and the random baseline are charged the
same way.
"""

from __future__ import annotations

import os
import resource
import time
from pathlib import Path

from service.core.motion.poses import DRIVER

TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds() -> float:
    """This process, its finished children, and the warm SUMO worker while it runs."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = time.process_time() + children.ru_utime + children.ru_stime
    process = DRIVER._process  # the warm worker is the only child alive between calls
    if process is not None and process.poll() is None:
        fields = Path(f"/proc/{process.pid}/stat").read_text().rsplit(")", 1)[1].split()
        total += (int(fields[11]) + int(fields[12])) / TICKS
    return total
