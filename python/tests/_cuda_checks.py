"""The check runner of python/tests/cuda_torch.py and cuda_zerocopy.py. Those run by path on the
GPU machine (not collected by pytest), so they import this from beside them.
"""

from __future__ import annotations

import traceback
from typing import Callable, Dict

# Each check's outcome by name: "PASS" or "FAIL: why".
results: Dict[str, str] = {}


def check(name: str) -> Callable[[Callable[[], None]], Callable[[], None]]:
    """Runs the function it decorates at once, as the check `name`: prints and records its outcome."""

    def run(f: Callable[[], None]) -> Callable[[], None]:
        try:
            f()
            results[name] = "PASS"
            print(f"PASS {name}", flush=True)
        except Exception as e:  # a check that fails reports and the others still run
            results[name] = f"FAIL: {type(e).__name__}: {e}"
            print(f"FAIL {name}: {type(e).__name__}: {e}", flush=True)
            traceback.print_exc()
        return f

    return run


def tally() -> int:
    """Prints how many checks passed and failed; returns the failures (the scripts' exit status)."""
    failed = sum(r != "PASS" for r in results.values())
    print(f"{len(results) - failed} passed, {failed} failed")
    return failed
