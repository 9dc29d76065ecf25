"""Markdown tables in the layout of the paper's Tables 1 and 2, best value per column in bold."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from lfsam.metrics import METRICS, Metric

__all__ = ["format_metrics_table", "format_value"]


def format_value(value: float | None, digits: int) -> str:
    """A metric as shown in a table: fixed decimals, ``n/a`` when missing or NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def _best(values: list[str], metric: Metric) -> set[int]:
    """Rows holding the best displayed value of a column (ties all count)."""
    numbers = {i: float(v) for i, v in enumerate(values) if v != "n/a"}
    if len(numbers) < 2:
        return set()
    target = max(numbers.values()) if metric.higher_is_better else min(numbers.values())
    return {i for i, v in numbers.items() if v == target}


def format_metrics_table(
    rows: Sequence[tuple[str, Mapping[str, float | None]]],
    first_column: str = "Method",
    mark_best: bool = True,
    metrics: Sequence[Metric] = METRICS,
) -> str:
    """A markdown table with one row per method and the columns of paper Table 1.

    Parameters
    ----------
    rows : sequence of (name, metrics)
        Row label and its metric values keyed as in :data:`lfsam.metrics.METRICS`.
    first_column : str
        Title of the label column.
    mark_best : bool
        Bold the best value of each column (by each metric's direction, compared as displayed),
        as in the paper's tables; only when at least two rows have a value.
    metrics : sequence of Metric
        Columns to show.

    Returns
    -------
    str
        The table, ending with a newline.
    """
    cells = [[format_value(values.get(m.key), m.digits) for m in metrics] for _, values in rows]
    if mark_best:
        for column, metric in enumerate(metrics):
            for row in _best([line[column] for line in cells], metric):
                cells[row][column] = f"**{cells[row][column]}**"
    header = [first_column, *(m.title for m in metrics)]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join(["---"] + [":---:"] * len(metrics)) + "|",
    ]
    for (name, _), line in zip(rows, cells, strict=True):
        lines.append("| " + " | ".join([name.replace("|", "/"), *line]) + " |")
    return "\n".join(lines) + "\n"
