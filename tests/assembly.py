"""Counting the diagnosis reports built (:class:`~vjm.discrepancy.stages.record.Report`): a report patched
after assembly (``dataclasses.replace`` builds a new one) counts twice."""
from vjm.discrepancy.stages import record


class Count:
    """Counts the Reports built while it is active (wraps ``Report.__post_init__``)."""

    def __init__(self):
        self.n = 0
        self._orig = record.Report.__post_init__

    def __enter__(self):
        def counted(rep):
            self.n += 1
            self._orig(rep)
        record.Report.__post_init__ = counted
        return self

    def __exit__(self, *exc):
        record.Report.__post_init__ = self._orig
