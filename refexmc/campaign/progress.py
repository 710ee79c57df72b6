"""Campaign progress on stderr: a tqdm bar on a terminal, a plain line every few seconds otherwise."""

import sys
import time

LINE_INTERVAL_S = 5.0


def progress_mode(stream=None):
    """'bar' when ``stream`` (default stderr) is a terminal, else 'lines'."""
    stream = stream or sys.stderr
    return "bar" if getattr(stream, "isatty", lambda: False)() else "lines"


class Progress:
    """Runs done out of ``total`` (``done`` of them before this invocation), runs/s and ETA.

    ``mode``: 'bar' (tqdm), 'lines' (a line every ``LINE_INTERVAL_S`` and one at the end) or None (silent).
    """

    def __init__(self, total, done=0, mode=None, stream=None):
        self.total = total
        self.done = done
        self.mode = mode
        self.stream = stream or sys.stderr
        self._start_done = done
        self._start = self._last_line = time.monotonic()
        self._bar = None
        if mode == "bar":
            from tqdm import tqdm

            self._bar = tqdm(total=total, initial=done, unit="run", file=self.stream, dynamic_ncols=True)

    def update(self, runs):
        self.done += runs
        if self._bar is not None:
            self._bar.update(runs)
        elif self.mode == "lines" and time.monotonic() - self._last_line >= LINE_INTERVAL_S:
            self._line()

    def close(self):
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.mode == "lines":
            self._line(final=True)
        self.mode = None

    def _line(self, final=False):
        now = time.monotonic()
        self._last_line = now
        elapsed = now - self._start
        flown = self.done - self._start_done
        rate = flown / elapsed if elapsed > 0 else 0.0
        text = f"{self.done}/{self.total} runs, {rate:.0f} runs/s"
        if final:
            text += f", {elapsed:.1f} s"
        elif rate > 0:
            text += f", ETA {(self.total - self.done) / rate:.0f} s"
        print(text, file=self.stream, flush=True)
