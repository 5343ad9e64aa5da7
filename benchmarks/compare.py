"""Compare two outputs of ``benchmarks/run.py``: ``python benchmarks/compare.py OLD.md NEW.md``.

Prints a markdown table of the figures both runs share (item 1-8 medians): old, new, new/old and
whether the new figure is better or worse (lower is better for times and memory, higher for
rates and ratios). Item 9 (the serial layers side by side) repeats items 2-4 and is left out.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path

_NUMBER = re.compile(r"([+-]?\d+(?:\.\d+)?)\s*([kM]?)")
NOISE = 0.10
"""A change smaller than this fraction is reported as 'same' (shared machine)."""


def rows(text: str) -> dict[tuple[str, str], str]:
    """``(item, measurement) -> median`` from the first markdown table of a run.py output."""
    found: dict[tuple[str, str], str] = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not cells[0].isdigit() or cells[0] == "9":
            continue
        found.setdefault((cells[0], cells[1]), cells[2])
    return found


def value(text: str) -> float | None:
    """The number in ``12 k lines/s``, ``0.301 ms``, ``16.21 MB/s``, ``+0.00 MB``, or None."""
    match = _NUMBER.search(text)
    if match is None:
        return None
    number = float(match.group(1))
    return number * {"": 1.0, "k": 1e3, "M": 1e6}[match.group(2)]


def lower_is_better(median: str) -> bool:
    return median.endswith(" ms") or median.endswith(" MB")


def compare(old: str, new: str) -> str:
    old_rows, new_rows = rows(old), rows(new)
    out = [
        "| # | Measurement | Old | New | New / old | Verdict |",
        "|---|---|---|---|---|---|",
    ]
    for key, new_median in new_rows.items():
        old_median = old_rows.get(key)
        if old_median is None:
            continue
        a, b = value(old_median), value(new_median)
        if a is None or b is None or a == 0:
            ratio, verdict = "-", "-"
        else:
            r = b / a
            ratio = f"{r:.3f}"
            better = r < 1 if lower_is_better(new_median) else r > 1
            if "RSS" in key[1]:  # +0.00 MB: noise around zero
                verdict = "same" if abs(b - a) < 1.0 else ("better" if better else "WORSE")
            elif abs(r - 1) < NOISE:
                verdict = "same"
            else:
                verdict = "better" if better else "WORSE"
        out.append(f"| {key[0]} | {key[1]} | {old_median} | {new_median} | {ratio} | {verdict} |")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    args = parser.parse_args(argv)
    print(compare(args.old.read_text(encoding="utf-8"), args.new.read_text(encoding="utf-8")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
