"""Writing a batch of rows so that one bad row never blocks the others.

The server's background writers (the event log, fleet state, mission outcomes, map upkeep)
gather rows and write them together. A row the database refuses (a robot deleted
meanwhile, a value a column cannot hold) must cost that row alone, never the batch again
and again; a database that cannot be reached (down, or SQLite busy past its timeout) must
cost nothing: what was not written is handed back to be written later.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

from django.db import InterfaceError, OperationalError, transaction

logger = logging.getLogger(__name__)

Row = TypeVar("Row")

# The database cannot be reached or is busy: worth another try later, unlike a refusal.
UNREACHABLE = (OperationalError, InterfaceError)


class BatchInterrupted(Exception, Generic[Row]):
    """The database could not be reached partway: ``unwritten`` rows are still to write
    (every other row of the batch was written or refused)."""

    def __init__(self, unwritten: list[Row]) -> None:
        super().__init__(f"{len(unwritten)} rows not written: the database is unreachable")
        self.unwritten = unwritten


def write_batch(
    rows: Sequence[Row], write: Callable[[Sequence[Row]], object], what: str
) -> list[Row]:
    """Write ``rows`` with ``write`` in one transaction; when the database refuses it, write
    each row in a transaction of its own. Returns the rows refused (each logged as one of
    ``what``). Raises ``BatchInterrupted`` with the rows not yet written when the database
    cannot be reached."""
    try:
        with transaction.atomic():
            write(rows)
        return []
    except UNREACHABLE as error:
        raise BatchInterrupted(list(rows)) from error
    except Exception:  # a refusal (DatabaseError, or text the driver cannot encode)
        pass
    refused: list[Row] = []
    for i, row in enumerate(rows):
        try:
            with transaction.atomic():
                write([row])
        except UNREACHABLE as error:
            raise BatchInterrupted(list(rows[i:])) from error
        except Exception as error:
            refused.append(row)
            logger.warning("%s not written, the database refused it: %s", what, error)
    return refused
