"""How numbers are written on the report: three significant digits, integers as integers, seconds
as s / min / h."""
import math


def number(v) -> str:
    """3 significant digits (1.23e-05, 0.0123, 12.3, 1.23e+04); integers up to 10^6 exactly."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    v = float(v)
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    return f"{v:.3g}"


def duration(seconds) -> str:
    """A wall time: '42 s', '12.5 min', '3.2 h'."""
    if seconds is None or (isinstance(seconds, float) and math.isnan(seconds)):
        return "n/a"
    s = float(seconds)
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    return f"{s / 3600:.3g} h"


def truthy(v) -> bool:
    """A boolean cell read back from a CSV: 'True', '1', '1.0', 'yes' (any case) are true."""
    return str(v).strip().lower() in ("true", "1", "1.0", "yes")
