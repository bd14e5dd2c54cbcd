"""What the Rerun viewer shows: entity paths, names, colours and the layout.

One place for every entity the Rerun sink writes, so that a name and a
colour mean the same thing in every view (the GNSS channel is the same blue
in the heights, the NIS and the state lanes). The layout is a
:func:`blueprint` sent once at the start of a run.

Entity paths (all on the ``vehicle_time`` timeline, seconds of vehicle time;
non-finite values are logged as NaN, a gap in the line)::

    heights/raw/{baro,gnss,rangefinder}   raw sensor heights (points; rangefinder is AGL)
    heights/autopilot                     the autopilot's own estimate
    heights/channel/{gnss,rangefinder,baro}  each channel's height estimate
    heights/fused                         fused height
    heights/fused_sigma                   [fused - sigma, fused + sigma]
    integrity/pairs/<pair>/diff           channel difference H_a - H_b (PAIR_NAMES), while valid
    integrity/pairs/<pair>/threshold      [+threshold, -threshold], while valid
    integrity/nis/<channel>               normalised innovation squared of the epoch
    integrity/norm_innov/<channel>        [baro row, aux row] innovation / sigma
    integrity/window/<source>             [window statistic, low bound, high bound]
    integrity/vpl                         vertical protection level
    integrity/alert_limit                 alert limit
    state/source/<source>                 nominal | caution | unavailable | alarm
    state/overall                         the worst source state
    state/channel/<channel>               used | available | unavailable
    alarms                                every AlarmEvent, as a text log entry
    input/rate/<kind>                     samples per second of vehicle time
    input/rejected/<kind>                 cumulative count of rejected samples
    input/gaps/<kind>                     length of each gap (s), at its end
    input/events                          gaps, reboots, link loss (text log)
"""

from __future__ import annotations

from typing import Optional

import rerun as rr
import rerun.blueprint as rrb

from ..report import CHANNEL_NAMES, PAIR_NAMES, SOURCES, STATES

TIMELINE = "vehicle_time"

Rgb = tuple[int, int, int]

# Sensor / channel colours (tab10), shared by raw heights, channel estimates,
# NIS and the source lanes of the same sensor.
CHANNEL_COLOURS: dict[str, Rgb] = {
    "gnss": (31, 119, 180),  # blue
    "rangefinder": (148, 103, 189),  # purple
    "baro": (255, 127, 14),  # orange
}
FUSED_COLOUR: Rgb = (235, 235, 235)
SIGMA_COLOUR: Rgb = (150, 150, 150)
AUTOPILOT_COLOUR: Rgb = (227, 119, 194)  # pink
PAIR_COLOURS: dict[str, Rgb] = {
    "gnss-rng": (23, 190, 207),  # teal
    "gnss-baro": (188, 189, 34),  # olive
    "rng-baro": (140, 86, 75),  # brown
}
SOURCE_COLOURS: dict[str, Rgb] = {
    "gnss": CHANNEL_COLOURS["gnss"],
    "rangefinder": CHANNEL_COLOURS["rangefinder"],
    "baro_ins": CHANNEL_COLOURS["baro"],
    "input": (199, 199, 199),
}
STATE_COLOURS: dict[str, Rgb] = {
    "nominal": (44, 160, 44),  # green
    "caution": (255, 200, 0),  # amber
    "unavailable": (127, 127, 127),  # grey
    "alarm": (214, 39, 40),  # red
}
CHANNEL_STATES = ("used", "available", "unavailable")
CHANNEL_STATE_COLOURS: dict[str, Rgb] = {
    "used": STATE_COLOURS["nominal"],
    "available": (120, 200, 120),
    "unavailable": STATE_COLOURS["unavailable"],
}
VPL_COLOUR: Rgb = (235, 235, 235)
ALERT_LIMIT_COLOUR: Rgb = STATE_COLOURS["alarm"]
# Text log level of an alarm event, by the state it enters.
STATE_LEVELS = {"nominal": "INFO", "caution": "WARN", "unavailable": "WARN", "alarm": "ERROR"}

# Input kinds counted for the rate plot, by sample type name.
RATE_KINDS: dict[str, str] = {
    "SpecificForceUp": "imu",
    "BaroHeight": "baro",
    "GnssHeight": "gnss",
    "RangeHeight": "range",
    "AutopilotHeight": "autopilot",
}
RATE_COLOURS: dict[str, Rgb] = {
    "imu": (199, 199, 199),
    "baro": CHANNEL_COLOURS["baro"],
    "gnss": CHANNEL_COLOURS["gnss"],
    "range": CHANNEL_COLOURS["rangefinder"],
    "autopilot": AUTOPILOT_COLOUR,
}
RAW_ENTITY = {"BaroHeight": "heights/raw/baro", "GnssHeight": "heights/raw/gnss", "RangeHeight": "heights/raw/rangefinder"}


def channel_entity(name: str) -> str:
    return f"heights/channel/{name}"


def pair_entity(name: str, what: str) -> str:
    return f"integrity/pairs/{name}/{what}"


def series_styles() -> list[tuple[str, object]]:
    """Static (entity, archetype) pairs that name and colour every series.

    Logged once, before any data; the sink adds styles for input kinds it
    discovers while running (see :func:`input_styles`).
    """
    out: list[tuple[str, object]] = []
    raw_names = {"baro": "baro (raw)", "gnss": "GNSS (raw)", "rangefinder": "rangefinder (raw, AGL)"}
    for ch in CHANNEL_NAMES:
        colour = CHANNEL_COLOURS[ch]
        out.append((f"heights/raw/{ch}", rr.SeriesPoints(colors=[colour], names=[raw_names[ch]], marker_sizes=[1.5])))
        out.append((channel_entity(ch), rr.SeriesLines(colors=[colour], names=[f"{ch} channel"], widths=[1.5])))
        out.append((f"integrity/nis/{ch}", rr.SeriesLines(colors=[colour], names=[f"NIS {ch}"], widths=[1.5])))
        out.append(
            (
                f"integrity/norm_innov/{ch}",
                rr.SeriesPoints(
                    colors=[colour, colour],
                    names=[f"{ch}: baro row", f"{ch}: aux row"],
                    markers=["circle", "cross"],
                    marker_sizes=[1.0, 1.5],
                ),
            )
        )
    out.append(("heights/autopilot", rr.SeriesLines(colors=[AUTOPILOT_COLOUR], names=["autopilot"], widths=[1.0])))
    out.append(("heights/fused", rr.SeriesLines(colors=[FUSED_COLOUR], names=["fused"], widths=[2.5])))
    out.append(
        (
            "heights/fused_sigma",
            rr.SeriesLines(colors=[SIGMA_COLOUR, SIGMA_COLOUR], names=["fused - sigma", "fused + sigma"], widths=[0.75, 0.75]),
        )
    )
    for pair in PAIR_NAMES:
        colour = PAIR_COLOURS[pair]
        out.append((pair_entity(pair, "diff"), rr.SeriesLines(colors=[colour], names=[pair], widths=[1.5])))
        out.append(
            (
                pair_entity(pair, "threshold"),
                rr.SeriesLines(colors=[colour, colour], names=[f"{pair} +threshold", f"{pair} -threshold"], widths=[0.75, 0.75]),
            )
        )
    for src in SOURCES:
        colour = SOURCE_COLOURS[src]
        out.append(
            (
                f"integrity/window/{src}",
                rr.SeriesLines(
                    colors=[colour, SIGMA_COLOUR, SIGMA_COLOUR],
                    names=[f"{src} window", f"{src} low", f"{src} high"],
                    widths=[1.5, 0.75, 0.75],
                ),
            )
        )
        out.append((f"state/source/{src}", state_configuration(STATES, STATE_COLOURS)))
    out.append(("state/overall", state_configuration(STATES, STATE_COLOURS)))
    for ch in CHANNEL_NAMES:
        out.append((f"state/channel/{ch}", state_configuration(CHANNEL_STATES, CHANNEL_STATE_COLOURS)))
    out.append(("integrity/vpl", rr.SeriesLines(colors=[VPL_COLOUR], names=["VPL"], widths=[1.5])))
    out.append(("integrity/alert_limit", rr.SeriesLines(colors=[ALERT_LIMIT_COLOUR], names=["alert limit"], widths=[1.5])))
    return out


def input_styles(group: str, kind: str) -> tuple[str, object]:
    """Style of an input-health series found while running (``group``: rate, rejected, gaps)."""
    colour = RATE_COLOURS.get(kind, (199, 199, 199))
    entity = f"input/{group}/{kind}"
    if group == "rate":
        return entity, rr.SeriesLines(colors=[colour], names=[f"{kind} rate"], widths=[1.5])
    if group == "rejected":
        return entity, rr.SeriesLines(colors=[colour], names=[f"rejected {kind}"], widths=[1.5])
    return entity, rr.SeriesPoints(colors=[colour], names=[f"gap {kind}"], marker_sizes=[4.0])


def state_configuration(values, colours: dict[str, Rgb]) -> object:
    return rr.StateConfiguration(values=list(values), colors=[colours[v] for v in values])


def blueprint(live: bool, window_s: float = 30.0) -> rrb.Blueprint:
    """The layout: heights and pair differences on top, integrity statistics
    and the state lanes in the middle, input health and the alarm log below.

    Live runs follow the cursor: every time view shows the last ``window_s``
    seconds of vehicle time; replays show the whole log.
    """
    ranges: Optional[rrb.VisibleTimeRange] = None
    if live:
        ranges = rrb.VisibleTimeRange(
            TIMELINE,
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-float(window_s)),
            end=rrb.TimeRangeBoundary.cursor_relative(),
        )

    def series(name: str, contents, **kw) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(origin="/", contents=contents, name=name, time_ranges=ranges, **kw)

    heights = series("Height (m)", ["heights/**"])
    pairs = series("Channel differences vs thresholds (m)", ["integrity/pairs/**"])
    nis = series("NIS and normalised innovations", ["integrity/nis/**", "integrity/norm_innov/**"])
    window = series("Window statistics", ["integrity/window/**"])
    vpl = series("Protection level vs alert limit (m)", ["integrity/vpl", "integrity/alert_limit"])
    states = rrb.StateTimelineView(origin="/", contents=["state/**"], name="States", time_ranges=ranges)
    rates = series("Input rates (Hz, vehicle time)", ["input/rate/**"])
    rejected = series("Rejected samples, gaps (s)", ["input/rejected/**", "input/gaps/**"])
    log = rrb.TextLogView(origin="/", contents=["alarms", "input/events"], name="Alarms and input events")
    layout = rrb.Vertical(
        rrb.Horizontal(heights, pairs, column_shares=[3, 2]),
        rrb.Horizontal(nis, window, vpl),
        states,
        rrb.Horizontal(rates, rejected, log, column_shares=[1, 1, 2]),
        row_shares=[3, 2, 3, 2],
    )
    return rrb.Blueprint(
        layout,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=TIMELINE, play_state="following" if live else None),
        auto_views=False,
    )
