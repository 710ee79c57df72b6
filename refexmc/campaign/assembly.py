"""What every execution backend shares: tasks, error rows, and the assembly of chunks from their pieces.

A backend flies each chunk as one :class:`Task`, or, after a crash, in pieces (runs flown again,
suspects flown alone, error rows the parent made); :class:`ChunkAssembler` puts the pieces back
together and hands out each chunk once all its runs are in. Used by :mod:`refexmc.campaign.backends`
(loky) and :mod:`refexmc.campaign.dask_backend`; it imports neither.
"""

import pyarrow as pa

from refexmc.campaign import storage

TASKS_PER_WORKER = 2  # chunks in flight per worker: one flying, one queued


class Task:
    """Runs of one chunk to fly together; ``isolated``: a crash suspect flown alone."""

    def __init__(self, chunk, run_ids, isolated=False):
        self.chunk = chunk
        self.run_ids = list(run_ids)
        self.isolated = isolated


def error_row(campaign, run_id, reason):
    """A runs row for a run that produced no result of its own (it hung, or crashed its worker)."""
    from refexmc.campaign.chunk import plan_for  # the flight kernels: only needed after a crash

    return plan_for(campaign).error_row(run_id, reason)


class ChunkAssembler:
    """Collects the pieces of each chunk (results of tasks, error rows) until all its runs are in."""

    def __init__(self, chunks):
        self._expected = {chunk: len(run_ids) for chunk, run_ids in chunks}
        self._rows = {}
        self._runs = {}
        self._histories = {}
        self._errors = set()

    def add(self, chunk, flown):
        """Add a worker's :class:`~refexmc.campaign.worker.Flown`; return the finished chunk or None."""
        if flown.history is not None:
            self._histories.setdefault(chunk, []).append(flown.history)
        return self._add_rows(chunk, flown.rows, flown.runs)

    def add_errors(self, chunk, rows):
        """Add error rows the parent made (runs that hung or crashed); return the finished chunk or None."""
        self._errors.update((chunk, row["run_id"]) for row in rows)
        return self._add_rows(chunk, rows, None)

    def _add_rows(self, chunk, rows, runs):
        self._rows.setdefault(chunk, []).extend(rows)
        self._runs.setdefault(chunk, []).append(runs)  # one entry per piece, None where not encoded
        if len(self._rows[chunk]) < self._expected[chunk]:
            return None
        rows = sorted(self._rows.pop(chunk), key=lambda row: row["run_id"])
        rows = self._align(chunk, rows)
        pieces = self._runs.pop(chunk)
        if len(pieces) == 1 and pieces[0] is not None:
            runs = pieces[0]  # one task flew the whole chunk, in run order
        else:
            runs = storage.encode_table(storage.runs_table(rows))
        return chunk, rows, runs, self._history(self._histories.pop(chunk, []))

    @staticmethod
    def _history(pieces):
        """One chunk's history file: the workers' bytes as they are when they came back in one piece."""
        if len(pieces) == 1:
            return pieces[0]  # one task flew the whole chunk, in run order
        if not pieces:
            return storage.encode_table(storage.empty_history_table())
        tables = [storage.decode_table(piece) for piece in pieces]
        return storage.encode_table(pa.concat_tables(tables).sort_by("run_id"))

    def _align(self, chunk, rows):
        """Give rows the parent made the columns (and order) of the rows the workers made."""
        made = [(chunk, row["run_id"]) in self._errors for row in rows]
        self._errors.difference_update((chunk, row["run_id"]) for row in rows)
        template = next((row for row, by_parent in zip(rows, made, strict=True) if not by_parent), None)
        if template is None:
            return rows
        return [
            {key: row.get(key) for key in template} if by_parent else row
            for row, by_parent in zip(rows, made, strict=True)
        ]
