"""The report's files: report.csv (long format), report.md (a table per knob, the Pareto fronts,
the feature costs) and error_vs_time.png (matplotlib, imported when the plot is drawn)."""
from __future__ import annotations

import csv
import math
from typing import Any, Sequence

from ._common import _SUPERSAMPLED, CSV_COLUMNS, Row, Settings, _require


# ----------------------------------------------------------------------------------- the report

def pareto_front(points: Sequence[tuple[float, float]]) -> list[int]:
    """Indices of the (time, error) points no other point beats on both (lower is better for
    both), in order of time: the fastest way to each error level."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _front_groups(rows: Sequence[Row]) -> dict[tuple[str, str, str], list[Row]]:
    """Rows by (scene, metric, reference): the points a Pareto front may compare (one reference,
    one metric). "higher is better" metrics are left out (their error is not an error), and so
    is the threads knob (it trades time alone; its rows repeat other knobs' configurations)."""
    groups: dict[tuple[str, str, str], list[Row]] = {}
    for r in rows:
        if r.better == "lower" and math.isfinite(r.error) and r.knob != "threads":
            groups.setdefault((r.scene, r.metric, r.reference), []).append(r)
    return groups


# The plot's panels and the Markdown's Pareto fronts: (scene, metric, title).
_PANELS = (
    ("sphere", "coverage_mean", "sphere: coverage error per edge pixel\n(mean |alpha - exact area|; alpha = mask without AA)"),
    ("sphere", "depth_max", "sphere: max depth error (scene units)\nvs exact ray-sphere hit"),
    ("sphere", "normal_mean_deg", "sphere: mean normal error (degrees)\nvs exact normal"),
    ("sphere", "rmse", "sphere: colour RMSE, lambert (linear)\nvs the closed form at pixel centres"),
    ("sphere", "rmse_box", "sphere: colour RMSE vs box filter\n(16x16-supersampled render)"),
    ("checker", "rmse", "grazing checkerboard: RMSE (linear)\nvs exact box filter"),
)


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.3g}" if math.isfinite(x) else str(x)
    return str(x)


def _write_csv(path: str, rows: Sequence[Row]) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for r in rows:
            d = r.as_dict()
            d["error"] = repr(float(r.error))
            d["time_ms"] = f"{r.time_ms:.4f}"
            d["time_spread_ms"] = f"{r.time_spread_ms:.4f}"
            writer.writerow(d)


def _write_markdown(path: str, rows: Sequence[Row], costs: Sequence[dict[str, Any]], header: Sequence[str],
                    settings: Settings) -> None:
    lines = ["# softrast: error against run time", ""] + list(header) + [""]
    lines += ["References (exact unless labelled): the sphere's silhouette is a disk, integrated over "
              "each pixel square in closed form; depth, point and normal are the exact ray-sphere hit at "
              "each pixel centre, and colour the shading model's formula there; the checkerboard is "
              f"integrated exactly over each pixel square. `{_SUPERSAMPLED}` marks the one reference "
              "that is a render (the box-filtered shaded sphere has no closed form). Errors: lower is "
              "better except psnr_db and ssim. Time: of a render of the linear colour alone, median of the "
              "timed renders (interquartile range); the machine's load shows in it.", ""]
    knobs: dict[str, list[Row]] = {}
    for r in rows:
        knobs.setdefault(r.knob, []).append(r)
    for knob, krows in knobs.items():
        metrics = list(dict.fromkeys(r.metric for r in krows))
        values = list(dict.fromkeys(r.value for r in krows))
        scene = krows[0].scene
        lines += [f"## {knob} ({scene})", ""]
        by_ref: dict[str, list[str]] = {}
        units: dict[str, str] = {}
        for r in krows:
            if r.metric not in by_ref.setdefault(r.reference, []):
                by_ref[r.reference].append(r.metric)
            units[r.metric] = r.unit
        lines += ["References: " + "; ".join(f"{', '.join(m)} against {ref}" for ref, m in by_ref.items())
                  + ". Units: " + "; ".join(f"{m} {u}" for m, u in units.items() if u) + ".", ""]
        lines.append("| value | setting | time ms (IQR) | " + " | ".join(metrics) + " |")
        lines.append("|---" * (3 + len(metrics)) + "|")
        for v in values:
            vrows = {r.metric: r for r in krows if r.value == v}
            first = next(iter(vrows.values()))
            lines.append(f"| {v} | {first.setting} | {first.time_ms:.3f} ({first.time_spread_ms:.3f}) | "
                         + " | ".join(_fmt(vrows[m].error) if m in vrows else "" for m in metrics) + " |")
        lines.append("")
    lines += ["## Pareto fronts", "",
              "The configurations no other beats on both time and error, fastest first, per scene, "
              "metric and reference (every knob's rows together).", ""]
    groups = _front_groups(rows)
    for scene, metric, _ in _PANELS:
        for (g_scene, g_metric, ref), grows in groups.items():
            if (g_scene, g_metric) != (scene, metric) or len(grows) < 2:
                continue
            front = pareto_front([(r.time_ms, r.error) for r in grows])
            items = ", ".join(f"{grows[i].knob}={grows[i].value} ({grows[i].time_ms:.3f} ms, "
                              f"{_fmt(grows[i].error)})" for i in front)
            lines += [f"- {scene} {metric} against {ref}: {items}"]
    width, height = settings.cost_size
    lines += ["", "## What a scene pays for", "",
              f"The sphere scene at {width}x{height} (ico{settings.cost_subdivision}, "
              f"{20 * 4 ** settings.cost_subdivision} faces; a mesh without a material, "
              "lambert under the headlight, unless stated), each feature off, then on; the difference "
              "is against the group's first row.", ""]
    lines += ["| feature | setting | time ms (IQR) | difference ms |", "|---|---|---|---|"]
    for c in costs:
        lines.append(f"| {c['group']} | {c['setting']} | {c['time_ms']:.3f} ({c['time_spread_ms']:.3f}) | "
                     f"{c['delta_ms']:+.3f} |")
    lines += [""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def _log_ticks(axis: Any) -> None:
    """Plain labels (0.2, 5, 1e-05) on a log axis: every decade, also 2 and 5 when the axis spans
    less than three decades, evenly spaced values when it spans less than one (matplotlib's
    default labels every minor tick of a short axis, overlapping)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    lo, hi = axis.get_view_interval()
    if hi / lo < 10.0:
        axis.set_major_locator(MaxNLocator(nbins=5))
    else:
        axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0) if hi / lo < 1e3 else (1.0,)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


_NOT_PLOTTED = ("shading_model",)  # each model against its own closed form: no common curve


def _plot(path: str, rows: Sequence[Row], title: str) -> None:
    """error_vs_time.png: one log-log panel per (scene, metric) of _PANELS, one curve per knob
    (points in the knob's order, labelled with its values, horizontal bars the time's IQR), the
    Pareto front of the panel's main reference as a black dashed staircase through circled points.
    Zero errors (no log) and the knobs of _NOT_PLOTTED are left to the tables."""
    _require("matplotlib", "matplotlib")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 9.5), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3).ravel()
    colours = {"tessellation": "tab:blue", "frequency": "tab:orange", "shading_model": "tab:green",
               "threads": "tab:red", "texture_filter": "tab:purple", "max_anisotropy": "tab:brown",
               "msaa": "tab:cyan", "ssaa": "tab:pink", "shadow_resolution": "tab:olive"}
    groups = _front_groups(rows)
    for ax, (scene, metric, panel_title) in zip(axes, _PANELS):
        prows = [r for r in rows if r.scene == scene and r.metric == metric and r.error > 0.0
                 and r.knob not in _NOT_PLOTTED]
        knobs = list(dict.fromkeys(r.knob for r in prows))
        for knob in knobs:
            krows = [r for r in prows if r.knob == knob]
            x = [r.time_ms for r in krows]
            y = [r.error for r in krows]
            spread = [r.time_spread_ms / 2.0 for r in krows]
            ax.errorbar(x, y, xerr=spread, marker="o", ms=4, lw=1.2, capsize=2,
                        color=colours.get(knob), label=knob)
            for r in krows:
                ax.annotate(str(r.value), (r.time_ms, r.error), textcoords="offset points", xytext=(4, 3),
                            fontsize=6.5, color=colours.get(knob))
        # The front over the rows that share the panel's most common reference.
        refs = [r.reference for r in prows]
        if refs:
            main_ref = max(set(refs), key=refs.count)
            grows = [r for r in groups.get((scene, metric, main_ref), []) if r.error > 0.0]
            front = [grows[i] for i in pareto_front([(r.time_ms, r.error) for r in grows])]
            if len(front) >= 1:
                ax.plot([r.time_ms for r in front], [r.error for r in front], "k--", lw=0.9,
                        drawstyle="steps-post", label="Pareto front", zorder=0)
                ax.scatter([r.time_ms for r in front], [r.error for r in front], s=90, facecolors="none",
                           edgecolors="k", linewidths=1.0, zorder=3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _log_ticks(ax.xaxis)
        _log_ticks(ax.yaxis)
        ax.set_title(panel_title, fontsize=9.5)
        ax.set_xlabel("render time, ms (median; bars: IQR)", fontsize=8)
        ax.tick_params(labelsize=7.5)
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        if knobs:
            ax.legend(fontsize=7.5, loc="best")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path)
