"""A robot's calibration history drawn: each parameter's value over time with its ±1σ
and ±3σ bars, the changes larger than the threshold marked (``cellcal history --plot``).

:func:`write_history_plot` writes a PNG, or an HTML page (the figure embedded, and the
flagged changes as a table) for ``.html``; the file is replaced atomically.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
from pathlib import Path

import matplotlib.dates as mdates
import numpy as np
from matplotlib.figure import Figure

from calibration.diagnosis.history import ParameterHistory
from calibration.files import write_atomic

from .figures import png_bytes, style

_VALUE = "#1f6fb4"
_FLAG = "#c0392b"


def _utc(t: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(float(t), dt.UTC).replace(tzinfo=None)


def history_figure(histories: list[ParameterHistory], times: np.ndarray, title: str) -> Figure:
    """Small multiples, one per parameter: value ± std (thick ±1σ, thin ±3σ) at the
    calibrations' times (UTC); a flagged change drawn as a red segment."""
    n = max(len(histories), 1)
    cols = 1 if n == 1 else 2 if n <= 6 else 3
    rows = -(-n // cols)
    fig = Figure(figsize=(4.2 * cols + 0.6, 2.3 * rows + 0.7), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    for ax in axes[len(histories):]:
        ax.set_visible(False)
    for ax, h in zip(axes, histories, strict=False):
        x = [_utc(times[i]) for i in h.index]
        std = np.where(np.isfinite(h.std), h.std, 0.0)
        ax.errorbar(x, h.value, yerr=3 * std, fmt="none", ecolor=_VALUE, alpha=0.35,
                    elinewidth=0.8, capsize=2)
        ax.errorbar(x, h.value, yerr=std, fmt="o-", color=_VALUE, ms=3.5, lw=1.0,
                    elinewidth=2.2, capsize=0)
        for k in np.flatnonzero(h.flagged):
            ax.plot(x[k:k + 2], h.value[k:k + 2], color=_FLAG, lw=2.2, zorder=4)
            ax.annotate(f"{h.z[k]:.0f}σ", (x[k + 1], h.value[k + 1]), color=_FLAG,
                        fontsize=7.5, xytext=(4, 4), textcoords="offset points")
        ax.set_title(h.name + (" (changed)" if h.flagged.any() else ""),
                     color=_FLAG if h.flagged.any() else "black")
        ax.set_ylabel(h.unit)
        locator = mdates.AutoDateLocator(minticks=3, maxticks=8)
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    fig.suptitle(title)
    return fig


def _table(rows: list[list[str]], header: list[str]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def write_history_plot(path, histories: list[ParameterHistory], times: np.ndarray,
                       title: str, flagged_rows: list[list[str]] | None = None,
                       dpi: int = 110) -> Path:
    """Write the history figure to ``path``: ``.png``, or ``.html`` (the figure and the
    ``flagged_rows`` table: parameter, from, to, change, sigma)."""
    path = Path(path)
    with style():
        png = png_bytes(history_figure(histories, times, title), dpi)
    if path.suffix.lower() == ".png":
        data = png
    else:
        b64 = base64.b64encode(png).decode("ascii")
        flagged = (_table(flagged_rows, ["parameter", "from", "to", "change", "sigma"])
                   if flagged_rows else "<p>No change larger than the threshold.</p>")
        data = ("<!DOCTYPE html>\n<html><head><meta charset='utf-8'>"
                f"<title>{html.escape(title)}</title><style>body{{font-family:sans-serif;"
                "max-width:1400px;margin:1em auto}}table{{border-collapse:collapse}}"
                "td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}"
                f"img{{max-width:100%}}</style></head><body><h1>{html.escape(title)}</h1>"
                f"<h2>Changes larger than the threshold</h2>{flagged}"
                f"<h2>Parameters over time</h2><img alt='{html.escape(title)}' "
                f"src='data:image/png;base64,{b64}'></body></html>\n").encode()
    write_atomic(path, data)  # an interrupted write leaves the old file whole
    return path
