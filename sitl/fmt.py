"""Number formatting of the SitL tables (table1.py, study.py, and the README tables made from them by
report/readme_tables.py): a ratio and its interval printed with as many significant digits as it
takes to tell them apart."""
import math


def ratio_digits(*values, least: int = 3, most: int = 6) -> int:
    """The significant digits, from `least` to `most`, at which the distinct finite `values` (a ratio
    and the ends of its interval) print as distinct numbers, none but 1 itself as "1": 1.0002
    [1.0001, 1.0003] rather than 1 [1, 1], which reads as "no difference" next to a verdict of
    "higher"."""
    finite = {float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)
              and math.isfinite(v)}
    for d in range(least, most + 1):
        texts = {v: f"{v:.{d}g}" for v in finite}
        if len(set(texts.values())) == len(finite) and all(t != "1" or v == 1.0 for v, t in texts.items()):
            return d
    return most
