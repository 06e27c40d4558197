"""What bench_torch.py and bench_zerocopy.py share: point counts as given on the command line,
and timing in the caller's CUDA stream. They run by path, so they import this from beside them.
"""

from __future__ import annotations

import statistics
import time
from typing import Any, Callable, Dict

import torch


def count(text: str) -> int:
    text = text.strip().upper()
    scale = {"K": 1e3, "M": 1e6, "G": 1e9}.get(text[-1:], 1)
    return int(float(text.rstrip("KMG")) * scale)


def timed(dev: torch.device, f: Callable[[], Any], repeats: int, warm: bool = False) -> Dict[str, float]:
    """Seconds of `f` between two events on the current stream (on the CPU: wall time), best and
    median of `repeats`; `warm`: one untimed call first (buffers grow, pipelines compile)."""
    if warm:
        f()
    times = []
    for _ in range(repeats):
        if dev.type == "cuda":
            start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
            start.record()
            f()
            end.record()
            end.synchronize()
            times.append(start.elapsed_time(end) / 1e3)
        else:
            t0 = time.perf_counter()
            f()
            times.append(time.perf_counter() - t0)
    return {"best_s": min(times), "median_s": statistics.median(times)}
