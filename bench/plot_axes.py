"""plot_axes.py — numbers on short log axes for the bench/ plots (imported by plot*.py beside it).

matplotlib labels a log axis at whole decades only, so an axis spanning one or two decades (a
time from 20 to 90 ms, a volume error from 0.02 to 0.5) shows one number or none. number_log_axes
labels such axes at 1, 2 and 5 times the decades instead. Call it before tight_layout, which
must make room for the labels it adds.
"""
import math

from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter


def tick_text(value, _position=None):
    """0.002, 50, 2000 as plain numbers; smaller or larger as m×10ⁿ (mathtext)."""
    if value <= 0 or not math.isfinite(value):
        return ""
    if 1e-3 <= value < 1e5:
        return f"{value:g}"
    exponent = math.floor(math.log10(value) + 1e-9)
    mantissa = value / 10 ** exponent
    lead = "" if abs(mantissa - 1) < 1e-6 else f"{mantissa:g}\\times"
    return f"${lead}10^{{{exponent}}}$"


def number_log_axes(fig, max_decades=2.0):
    """Every base-10 log axis of `fig` spanning under `max_decades` decades gets major ticks at 1,
    2 and 5 times the decades, each labelled (call after the data are drawn, before saving)."""
    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale != "log" or getattr(axis.get_transform(), "base", 10) != 10:
                continue
            lo, hi = sorted(axis.get_view_interval())
            if not (lo > 0 and math.isfinite(hi)) or math.log10(hi / lo) >= max_decades:
                continue
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FuncFormatter(tick_text))
            axis.set_minor_formatter(NullFormatter())
