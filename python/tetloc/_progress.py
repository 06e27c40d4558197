"""The ``progress=True`` display: one line on stderr with the stage, a bar when the fraction
is known, and the elapsed time. Short tasks print nothing."""

from __future__ import annotations

import sys
from typing import Optional, TextIO


class ProgressBar:
    """Called by the extension as ``bar(stage, fraction or None, seconds)``; the stage
    ``"done"`` ends the line."""

    WIDTH = 24
    SPIN = "|/-\\"

    def __init__(self, title: str, stream: Optional[TextIO] = None, after_seconds: float = 0.5):
        self.title = title
        self.stream = stream if stream is not None else sys.stderr
        self.after_seconds = after_seconds
        self.shown = False
        self.ticks = 0

    def __call__(self, stage: str, fraction: Optional[float], seconds: float) -> None:
        if stage == "done":
            if self.shown:
                self._write(f"{self.title}: done", 1.0, seconds)
                self.stream.write("\n")
                self.stream.flush()
                self.shown = False
            return
        if seconds < self.after_seconds:
            return
        self.shown = True
        self.ticks += 1
        self._write(f"{self.title}: {stage}", fraction, seconds)

    def _write(self, text: str, fraction: Optional[float], seconds: float) -> None:
        if fraction is None:
            bar = self.SPIN[self.ticks % len(self.SPIN)]
        else:
            full = int(round(max(0.0, min(1.0, fraction)) * self.WIDTH))
            bar = "[" + "#" * full + "." * (self.WIDTH - full) + f"] {100 * fraction:3.0f}%"
        self.stream.write(f"\r{text} {bar} {seconds:6.1f} s\x1b[K")
        self.stream.flush()
