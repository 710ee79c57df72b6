"""Campaign progress on stderr: a tqdm bar on a terminal, a plain line every few seconds otherwise.

The first runs of a campaign carry the workers' start and the flight code's JIT compile (numba,
~15-25 s per vehicle family when not cached): until the first runs are done the progress says
"compiling", and the rate and ETA are measured from then on, so the compile does not inflate
the ETA (a 36 s campaign once showed "ETA 1022 s" on its first line).
"""

import sys
import time

LINE_INTERVAL_S = 5.0
COMPILING = "compiling the flight code (JIT, cached after the first campaign) and flying the first runs"


class Progress:
    """Runs done out of ``total`` (``done`` of them before this invocation), runs/s and ETA.

    ``mode``: 'bar' (tqdm), 'lines' (a line every ``LINE_INTERVAL_S`` and one at the end) or None (silent).
    ``start=False``: nothing is shown until :meth:`start` (a meter made before its campaign is checked).
    """

    def __init__(self, total, done=0, mode=None, stream=None, start=True):
        self.total = total
        self.done = done
        self.mode = mode
        self.stream = stream or sys.stderr
        self._timed_from = None  # (time, runs done) when the first runs ended: the rate counts from there
        self._bar = None
        self._started = False
        if start:
            self.start()

    def start(self):
        """Show the meter (once): the clock starts here."""
        if self._started:
            return
        self._started = True
        self._start = self._last_line = time.monotonic()
        if self.mode == "bar":
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, initial=self.done, unit="run", file=self.stream, dynamic_ncols=True)
            self._bar.set_description_str("compiling", refresh=True)
        elif self.mode == "lines" and self.done < self.total:
            print(f"{self.done}/{self.total} runs: {COMPILING}; ETA once they are done", file=self.stream, flush=True)

    def update(self, runs):
        self.done += runs
        first = self._timed_from is None
        if first:
            self._timed_from = (time.monotonic(), self.done)
        if self._bar is not None:
            if first:  # restart tqdm's clock and rate here: the compile is not a run's time
                self._bar.set_description_str("", refresh=False)
                self._bar.reset(total=self.total)
                self._bar.n = self._bar.last_print_n = self._bar.initial = self.done
                self._bar.refresh()
            else:
                self._bar.update(runs)
        elif self.mode == "lines" and time.monotonic() - self._last_line >= LINE_INTERVAL_S:
            self._line()

    def close(self):
        if not self._started:  # never shown: nothing to end
            self.mode = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.mode == "lines":
            self._line(final=True)
        self.mode = None

    def rate(self, now=None):
        """Runs per second since the first runs ended (None before the next runs are timed)."""
        if self._timed_from is None:
            return None
        since, done = self._timed_from
        elapsed = (time.monotonic() if now is None else now) - since
        return (self.done - done) / elapsed if elapsed > 0 and self.done > done else None

    def _line(self, final=False):
        now = time.monotonic()
        self._last_line = now
        elapsed = now - self._start
        text = f"{self.done}/{self.total} runs"
        rate = self.rate(now)
        if final:
            text += f", {elapsed:.1f} s" + (f", {rate:.0f} runs/s after the first runs" if rate else "")
        elif rate is None:
            first = self._timed_from[0] - self._start
            text += f", the first in {first:.0f} s (JIT compile included); ETA once the next runs are timed"
        else:
            text += f", {rate:.0f} runs/s, ETA {(self.total - self.done) / rate:.0f} s"
        print(text, file=self.stream, flush=True)


def progress_mode(stream=None):
    """'bar' when ``stream`` (default stderr) is a terminal, else 'lines'."""
    stream = stream or sys.stderr
    return "bar" if getattr(stream, "isatty", lambda: False)() else "lines"
