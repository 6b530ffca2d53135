"""What every report figure shares: labelled log axes and compact encoding.

**Log ticks.** Matplotlib's own log locators leave an axis without a single label in two common
cases: a span under a decade (only minor ticks fall inside, and they are unlabelled or overprint)
and a span of many decades with a 1-2-5 sub-grid (the formatter then labels nothing). A reader
of an error axis needs numbers, so :func:`log_ticks` places the ticks itself from the final
limits: every decade, 1-2-5 or every mantissa when the span is short, a linear grid when no
mantissa falls inside, and every k-th decade when it is long, always at least two labels.

**Encoding.** :func:`encode` returns the smaller of a palette PNG (the figure's few flat
colours quantised to 64, which keeps lines and text exact and cuts the file about four-fold)
and, for figures with few plotted points, an SVG with text kept as text. Report pages embed the
result, so its size is the page's size.
"""

from __future__ import annotations

import io
import math

import numpy as np

PNG_DPI = 80  # a 6.4 in wide figure is 512 px: sized for a screen, not for print
PALETTE = 64
# An SVG grows with every plotted vertex, a PNG with the pixel count: above this many vertices
# the SVG is never the smaller one, so it is not even rendered.
VECTOR_MAX_POINTS = 1500


def _mantissa_ticks(lo: float, hi: float, mantissas) -> list[float]:
    out = []
    for k in range(math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 1):
        for m in mantissas:
            v = m * 10.0 ** k
            if lo * (1 - 1e-9) <= v <= hi * (1 + 1e-9):
                out.append(v)
    return out


def log_tick_values(lo: float, hi: float) -> tuple[list[float], list[float]]:
    """(labelled ticks, unlabelled minor ticks) for a log axis from ``lo`` to ``hi`` (> 0)."""
    from matplotlib import ticker

    span = math.log10(hi / lo)
    if span <= 8:
        major = []
        for mantissas in ((1,), (1, 2, 5), tuple(range(1, 10))):
            major = _mantissa_ticks(lo, hi, mantissas)
            if len(major) >= 3 or (len(major) >= 2 and span > 2):
                break
        if len(major) < 2:  # a sliver of a decade: a linear grid inside it
            major = [v for v in ticker.MaxNLocator(4).tick_values(lo, hi) if lo <= v <= hi]
        minor = [v for v in _mantissa_ticks(lo, hi, range(1, 10)) if v not in major]
        return major, minor
    stride = math.ceil(span / 7)
    first = math.ceil(math.log10(lo))
    decades = [10.0 ** k for k in range(first, math.floor(math.log10(hi)) + 1)]
    major = [v for v in decades if round(math.log10(v) - first) % stride == 0]
    return major, [v for v in decades if v not in major]


def tick_texts(values: list[float]) -> list[str]:
    """1e-4, 2e-4, 3.5e-4 (or 0.5, 20 when every tick is between 0.01 and 9999): short, and
    the way the report's tables write numbers; one style per axis."""
    if all(1e-2 <= v < 1e4 for v in values):
        return [f"{v:.4g}" for v in values]
    out = []
    for v in values:
        mantissa, exponent = f"{v:.2e}".split("e")
        out.append(f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}")
    return out


def log_ticks(ax, which: str = "y") -> None:
    """Labelled ticks on the log axis (axes) ``which`` ("x", "y", "both"), from the current
    limits; call once everything is drawn (the limits are frozen so the ticks stay true)."""
    from matplotlib import ticker

    for name in ("x", "y") if which == "both" else (which,):
        axis = ax.xaxis if name == "x" else ax.yaxis
        get, set_ = (ax.get_xlim, ax.set_xlim) if name == "x" else (ax.get_ylim, ax.set_ylim)
        lo, hi = sorted(get())
        if not (lo > 0 and math.isfinite(hi) and hi > lo):
            continue
        set_(lo, hi)
        major, minor = log_tick_values(lo, hi)
        axis.set_major_locator(ticker.FixedLocator(major))
        axis.set_major_formatter(ticker.FixedFormatter(tick_texts(major)))
        axis.set_minor_locator(ticker.FixedLocator(minor))
        axis.set_minor_formatter(ticker.NullFormatter())


def _vertices(fig) -> int:
    n = 0
    for ax in fig.axes:
        for line in ax.get_lines():
            n += len(line.get_xdata())
        for coll in ax.collections:
            n += len(coll.get_offsets()) + sum(len(p.vertices) for p in coll.get_paths())
    return n


def png(fig, dpi: int = PNG_DPI) -> bytes:
    """A palette PNG of the figure (falls back to matplotlib's RGBA PNG without Pillow)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow comes with matplotlib
        return buf.getvalue()
    image = Image.open(io.BytesIO(buf.getvalue())).convert("RGB")
    out = io.BytesIO()
    image.quantize(PALETTE, method=Image.Quantize.FASTOCTREE).save(out, "PNG", optimize=True)
    return out.getvalue() if out.tell() < len(buf.getvalue()) else buf.getvalue()


def svg(fig) -> bytes:
    import matplotlib

    buf = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "crosscheck"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def encode(fig, dpi: int = PNG_DPI) -> tuple[bytes, str]:
    """(bytes, MIME type): the smaller of the palette PNG and (few points only) the SVG."""
    raster = png(fig, dpi)
    if _vertices(fig) > VECTOR_MAX_POINTS:
        return raster, "image/png"
    vector = svg(fig)
    return (vector, "image/svg+xml") if len(vector) < len(raster) else (raster, "image/png")


def finite_positive(values) -> np.ndarray:
    a = np.asarray([v for v in values if v is not None], float)
    return a[np.isfinite(a) & (a > 0)]
