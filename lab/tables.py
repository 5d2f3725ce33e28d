"""Metrics tables (csv): rewritten whole from the rows of exactly the runs of the current config, so
a removed method or a switched dtype leaves no stale row behind, and read back with an error naming
the file."""
from pathlib import Path
from typing import Optional

from .atomic import write_text
from .deliver import note_input
from .io import MissingOutput, OutputError
from .stamp import note_current


def write_table(path, rows: list, sort: Optional[list] = None, ascending=True, columns: Optional[list] = None):
    """Rewrite the csv table `path` from `rows` (atomically). Returns the DataFrame. With no rows
    (no run of the current config has finished) the table is removed: an old one would list runs
    that are not the config's, and a csv without columns cannot be read back.

    `columns`: a fixed schema, exactly these columns in this order (a key a row lacks is an empty
    cell, a key not listed is left out), each value written as it is (`str`, no dtype inference: an
    integer column with an empty cell stays `3`, not `3.0`); then a table with no rows keeps its
    header."""
    import pandas as pd

    path = Path(path)
    note_current(path)  # the run step's stamp lists it (lab.stamp)
    if columns is not None:
        cell = lambda v: "" if v is None else str(v)  # noqa: E731 (as the csv module writes a value)
        df = pd.DataFrame([[cell(r.get(k)) for k in columns] for r in rows], columns=list(columns), dtype=object)
        write_text(path, df.to_csv(index=False))
        return df
    df = pd.DataFrame(rows)
    if df.empty:
        path.unlink(missing_ok=True)
        return df
    if sort:
        df = df.sort_values(sort, ascending=ascending, ignore_index=True)
    write_text(path, df.to_csv(index=False))
    return df


def read_table(path):
    """A metrics csv written by `write_table`, with an error naming the file when it is damaged."""
    import pandas as pd

    note_input(path)  # a deliverable made from it is re-made when it changes (lab.deliver)
    if not Path(path).exists():
        raise MissingOutput(f"{path}: no metrics table (no run of the current config has finished); run its "
                                "experiment first")
    try:
        return pd.read_csv(path)
    except Exception as e:  # pandas raises several types for empty, binary or malformed files
        raise OutputError(f"{path}: damaged metrics table ({type(e).__name__}: {e}); re-run its experiment "
                           "(make rebuilds it from the trajectories)") from None
