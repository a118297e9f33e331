"""Trend figures of a monitoring run: one PNG per parameter, posterior against date.

Per vehicle (one colour each): the posterior median (marker) and equal-tailed 95 %
interval (bar) of every campaign against its date; the acceptable domain as a
green band, the admissible interval C_w as dashed lines (the y-range), the nominal
as a dotted line; campaigns that raise or confirm an alarm ringed in red with their
P(outside); campaigns whose calibration is not trusted drawn hollow in a grey frame (they
never raise or clear an alarm; an alarm they carry over is ringed in light red); the truth
as a black cross when the data are synthetic; a note when the rig gives no acceptable
domain. Values in physical units with SI prefixes.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from susp_bo.units import unit_scale


def trend_figure(payload: Mapping[str, Any], name: str, path: Path) -> Path:
    """The trend of one parameter over every campaign of ``payload`` (``monitor.json``),
    saved to ``path``; returns it."""
    fig = trend_plot(payload, name)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def trend_plot(payload: Mapping[str, Any], name: str) -> Figure:
    """The open figure of :func:`trend_figure` (for tests and notebooks)."""
    k = list(payload["parameters"]).index(name)
    unit = payload["units"][k]
    lower, upper = payload["bounds"][k]
    acceptable = payload["acceptable"][k]
    factor, label = unit_scale(max(abs(lower), abs(upper)), unit)
    fig, ax = plt.subplots(figsize=(8.0, 4.2), constrained_layout=True)
    if acceptable is not None:
        ax.axhspan(
            acceptable[0] / factor, acceptable[1] / factor, color="tab:green", alpha=0.12, lw=0
        )
        for edge in acceptable:  # edges drawn too: a band narrow against C_w stays visible
            ax.axhline(edge / factor, color="tab:green", lw=0.8, alpha=0.7)
    for bound in (lower, upper):
        ax.axhline(bound / factor, color="0.4", ls="--", lw=0.9)
    ax.axhline(payload["nominal"][k] / factor, color="0.4", ls=":", lw=0.9)
    vehicles = list(payload["vehicles"])
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    offsets = np.linspace(-0.15, 0.15, len(vehicles)) if len(vehicles) > 1 else [0.0]
    handles: list[Any] = []
    any_alarm = any_carried = any_untrusted = any_truth = False
    for v, vehicle in enumerate(vehicles):
        colour = colours[v % len(colours)]
        rows = [r for r in payload["campaigns"] if r["vehicle"] == vehicle]
        dates = [dt.date.fromisoformat(r["date"]) for r in rows]
        x = mdates.date2num(dates) + offsets[v] * _spacing(payload)
        states = [r["parameters"][name] for r in rows]
        median = np.array([s["median"] for s in states]) / factor
        lo = np.array([s["interval95"][0] for s in states]) / factor
        hi = np.array([s["interval95"][1] for s in states]) / factor
        ax.errorbar(x, median, yerr=[median - lo, hi - median], fmt="none", ecolor=colour, lw=1.4)
        ax.plot(x, median, "-", color=colour, lw=0.6, alpha=0.6)
        trusted = np.array([r["trusted"] for r in rows], dtype=bool)
        ax.plot(x[trusted], median[trusted], "o", color=colour, ms=5)
        ax.plot(x[~trusted], median[~trusted], "o", mfc="white", mec=colour, ms=5)
        ax.plot(x[~trusted], median[~trusted], **_UNTRUSTED)  # a frame, seen under a cross
        any_untrusted |= bool(np.any(~trusted))
        alarm = np.array([s["alarm"] for s in states], dtype=bool)
        raised = alarm & trusted  # raised or confirmed by this campaign
        carried = alarm & ~trusted  # carried over a campaign that could not tell
        if np.any(raised):
            any_alarm = True
            ax.plot(x[raised], median[raised], **_ALARM)
            for xi, mi, state in zip(x[raised], median[raised], np.array(states)[raised]):
                ax.annotate(
                    f"P = {state['p_outside']:.3f}", (xi, mi), textcoords="offset points",
                    xytext=(0, 9), ha="center", fontsize=7, color="red",
                )  # fmt: skip
        if np.any(carried):
            any_carried = True
            ax.plot(x[carried], median[carried], **_CARRIED)
        truth = np.array([np.nan if s["truth"] is None else s["truth"] for s in states])
        if np.any(np.isfinite(truth)):
            any_truth = True
            ax.plot(x, truth / factor, "x", color="black", ms=6)
        handles.append(
            Line2D([], [], color=colour, marker="o", lw=1.4, label=f"{vehicle}: median, 95 %")
        )
    if acceptable is not None:
        handles.append(Patch(color="tab:green", alpha=0.25, label="acceptable domain"))
    else:
        handles.append(Patch(fill=False, lw=0, label="no acceptable domain: no alarm possible"))
    handles.append(Line2D([], [], color="0.4", ls="--", lw=0.9, label="admissible range $C_w$"))
    handles.append(Line2D([], [], color="0.4", ls=":", lw=0.9, label="nominal"))
    if any_alarm:
        handles.append(Line2D([], [], ls="none", label="alarm, P(outside)", **_ALARM))
    if any_carried:
        handles.append(
            Line2D([], [], ls="none", label="alarm carried over (campaign not trusted)", **_CARRIED)
        )
    if any_untrusted:
        handles.append(
            Line2D([], [], ls="none", label="not trusted: not used for alarms", **_UNTRUSTED)
        )
    if any_truth:
        handles.append(Line2D([], [], ls="none", marker="x", color="black", label="truth"))
    span = (upper - lower) / factor
    ax.set_ylim(lower / factor - 0.04 * span, upper / factor + 0.04 * span)
    ax.set_ylabel(f"{name} [{label}]")
    ax.set_xlabel("campaign date")
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%Y-%m-%d"))
    fig.autofmt_xdate()
    threshold = payload.get("alarm_threshold")
    rule = "" if threshold is None else f" (alarm: P(outside) > {threshold:g}, trusted only)"
    ax.set_title(f"{name}: posterior per campaign{rule}", fontsize=10)
    ax.legend(handles=handles, fontsize=7, loc="best", framealpha=0.85)
    ax.grid(alpha=0.25)
    return fig


_ALARM = {"marker": "o", "mfc": "none", "mec": "red", "ms": 11, "mew": 1.6}
_CARRIED = {"marker": "o", "mfc": "none", "mec": "salmon", "ms": 11, "mew": 1.2, "alpha": 0.8}
_UNTRUSTED = {"marker": "s", "mfc": "none", "mec": "0.35", "ms": 15, "mew": 1.0}


def _spacing(payload: Mapping[str, Any]) -> float:
    """Median gap between campaign dates (days), for the vehicle offsets."""
    dates = sorted({dt.date.fromisoformat(r["date"]) for r in payload["campaigns"]})
    if len(dates) < 2:
        return 1.0
    return float(np.median(np.diff(mdates.date2num(dates))))


def trend_figures(payload: Mapping[str, Any], out: Path) -> list[Path]:
    """``trend_<parameter>.png`` for every calibrated parameter, in ``out``."""
    return [
        trend_figure(payload, name, out / f"trend_{name}.png") for name in payload["parameters"]
    ]
