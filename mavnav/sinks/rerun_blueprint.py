"""What the Rerun viewer shows: entity paths, names, colours and the layout.

One place for every entity the Rerun sink writes, so that a name and a
colour mean the same thing in every view (the GNSS channel is the same blue
in the heights, the NIS and the state lanes). The layout is a
:func:`blueprint` sent once at the start of a run, in two tabs:

* **Pilot**: the current fused height and overall state in large type
  (``pilot/readout``, a Markdown document updated a few times a second and
  at every change of state), the fused height with its 1-sigma band, the
  raw heights of each sensor the monitor used, the autopilot's own height,
  the state strip (overall and per source) and the alarm table (alarms and
  what the input said: reboots, link loss, a moved home). The y axis
  follows what was used: raw samples the monitor refused (gated out, or
  from an excluded source) are on ``heights/rejected/*``, shown only on the
  engineering tab, so a faulty GNSS does not stretch the pilot's plot.
* **Engineering**: every height including the refused samples, channel
  differences against their thresholds, NIS and normalised innovations,
  window statistics, protection level against the alert limit, every state
  lane (channels too), input rates, rejected-sample counters and gaps, the
  input's event log.

Colours are chosen to read on the viewer's light and dark themes alike (no
near-white or near-black series). No legend covers a plot: where the series
are known in advance the view's title names their colours and the legend is
hidden (it can be shown from the view's settings; the two lines of a band
or of a +/- threshold share one entry). The pilot's tab shows the channel
estimates only through the fused height: its dots are what each sensor said.

Entity paths (all on the ``vehicle_time`` timeline, seconds of vehicle time;
non-finite values are logged as NaN, a gap in the line)::

    pilot/readout                         Markdown: fused height, sigma, state, what is wrong
    heights/raw/{baro,gnss,rangefinder}   raw heights the monitor used (points; rangefinder is AGL)
    heights/rejected/{baro,gnss,rangefinder}  raw heights it refused or excluded (engineering tab)
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
    input/events                          gaps, reboots, link loss, a moved home (text log)
"""

from __future__ import annotations

from typing import Optional

import rerun as rr
import rerun.blueprint as rrb

from ..report import CHANNEL_NAMES, PAIR_NAMES, SOURCES, STATES
from ..sensors import (AUTOPILOT_STREAM, BARO, BARO_INS, BARO_STREAM, GNSS, GNSS_STREAM, IMU_STREAM, INPUT,
                       RANGE_STREAM, RANGEFINDER)

TIMELINE = "vehicle_time"

Rgb = tuple[int, int, int]

# Sensor / channel colours (tab10), shared by raw heights, channel estimates,
# NIS and the source lanes of the same sensor.
CHANNEL_COLOURS: dict[str, Rgb] = {
    GNSS: (31, 119, 180),  # blue
    RANGEFINDER: (148, 103, 189),  # purple
    BARO: (255, 127, 14),  # orange
}
# Dark cyan: clear on the light theme's white and the dark theme's near-black,
# and a hue no sensor uses. The sigma band is the same hue, thinner.
FUSED_COLOUR: Rgb = (0, 139, 139)
SIGMA_COLOUR: Rgb = (0, 139, 139)
BOUND_COLOUR: Rgb = (128, 128, 128)  # window test bounds: mid grey reads on both themes
RAW_ALPHA = 170  # raw height dots, of 255
AUTOPILOT_COLOUR: Rgb = (227, 119, 194)  # pink
PAIR_COLOURS: dict[str, Rgb] = {
    "gnss-rng": (23, 190, 207),  # teal
    "gnss-baro": (165, 165, 25),  # olive (darker than tab10's, to read on white)
    "rng-baro": (140, 86, 75),  # brown
}
SOURCE_COLOURS: dict[str, Rgb] = {
    GNSS: CHANNEL_COLOURS[GNSS],
    RANGEFINDER: CHANNEL_COLOURS[RANGEFINDER],
    BARO_INS: CHANNEL_COLOURS[BARO],
    INPUT: (110, 110, 110),
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
VPL_COLOUR: Rgb = FUSED_COLOUR  # the fused height's protection level
ALERT_LIMIT_COLOUR: Rgb = STATE_COLOURS["alarm"]
# Text log level of an alarm event, by the state it enters.
STATE_LEVELS = {"nominal": "INFO", "caution": "WARN", "unavailable": "WARN", "alarm": "ERROR"}

# Input kinds counted for the rate plot, by sample type name.
RATE_KINDS: dict[str, str] = {
    "SpecificForceUp": IMU_STREAM,
    "BaroHeight": BARO_STREAM,
    "GnssHeight": GNSS_STREAM,
    "RangeHeight": RANGE_STREAM,
    "AutopilotHeight": AUTOPILOT_STREAM,
}
RATE_COLOURS: dict[str, Rgb] = {
    IMU_STREAM: (110, 110, 110),
    BARO_STREAM: CHANNEL_COLOURS[BARO],
    GNSS_STREAM: CHANNEL_COLOURS[GNSS],
    RANGE_STREAM: CHANNEL_COLOURS[RANGEFINDER],
    AUTOPILOT_STREAM: AUTOPILOT_COLOUR,
}
RAW_ENTITY = {"BaroHeight": "heights/raw/baro", "GnssHeight": "heights/raw/gnss", "RangeHeight": "heights/raw/rangefinder"}
READOUT = "pilot/readout"
SENSOR_WORDS = {c: c.word for c in CHANNEL_NAMES}  # GNSS, rangefinder, baro
SOURCE_WORDS = {s: s.word for s in SOURCES}  # GNSS, rangefinder, baro+INS, telemetry


def raw_entity(sensor: str, used: bool = True) -> str:
    """Where a raw height goes: ``heights/raw/<sensor>`` if the monitor used it, else ``heights/rejected/<sensor>``."""
    return f"heights/{'raw' if used else 'rejected'}/{sensor}"


def channel_entity(name: str) -> str:
    return f"heights/channel/{name}"


def pair_entity(name: str, what: str) -> str:
    return f"integrity/pairs/{name}/{what}"


def series_styles() -> list[tuple[str, object]]:
    """Static (entity, archetype) pairs that name and colour every series.

    Logged once, before any data; the sink adds styles for input kinds it
    discovers while running (see :func:`input_styles`). A sensor's raw
    points and its channel's line carry the sensor's colour and name
    distinct words; the two lines of a band or of a threshold share a name
    (one legend entry).
    """
    out: list[tuple[str, object]] = []
    raw_names = {BARO: "baro (raw)", GNSS: "GNSS (raw)", RANGEFINDER: "rangefinder (raw, AGL)"}
    for ch in CHANNEL_NAMES:
        colour = CHANNEL_COLOURS[ch]
        word = SENSOR_WORDS[ch]
        # small see-through dots: Rerun draws points over lines, and a dense sensor
        # (the rangefinder at 20 Hz on flat ground) lies right on the fused line
        out.append((raw_entity(ch), rr.SeriesPoints(colors=[(*colour, RAW_ALPHA)], names=[raw_names[ch]],
                                                    marker_sizes=[1.0])))
        out.append((raw_entity(ch, used=False),
                    rr.SeriesPoints(colors=[colour], names=[f"{word} (raw, not used)"], markers=["cross"],
                                    marker_sizes=[2.5])))
        out.append((channel_entity(ch), rr.SeriesLines(colors=[colour], names=[f"{word} channel"], widths=[1.5])))
        out.append((f"integrity/nis/{ch}", rr.SeriesLines(colors=[colour], names=[f"NIS {word}"], widths=[1.5])))
        out.append(
            (
                f"integrity/norm_innov/{ch}",
                rr.SeriesPoints(
                    colors=[colour, colour],
                    names=[f"{word}: baro row", f"{word}: aux row"],
                    markers=["circle", "cross"],
                    marker_sizes=[1.0, 1.5],
                ),
            )
        )
    out.append(("heights/autopilot", rr.SeriesLines(colors=[AUTOPILOT_COLOUR], names=["autopilot"], widths=[1.0])))
    out.append(("heights/fused", rr.SeriesLines(colors=[FUSED_COLOUR], names=["fused"], widths=[5.0])))
    out.append(
        (
            "heights/fused_sigma",
            rr.SeriesLines(colors=[SIGMA_COLOUR, SIGMA_COLOUR], names=["fused ±1σ", "fused ±1σ"], widths=[1.0, 1.0]),
        )
    )
    for pair in PAIR_NAMES:
        colour = PAIR_COLOURS[pair]
        out.append((pair_entity(pair, "diff"), rr.SeriesLines(colors=[colour], names=[pair], widths=[1.5])))
        out.append(
            (
                pair_entity(pair, "threshold"),
                rr.SeriesLines(colors=[colour, colour], names=[f"{pair} ±threshold"] * 2, widths=[0.75, 0.75]),
            )
        )
    for src in SOURCES:
        colour = SOURCE_COLOURS[src]
        out.append(
            (
                f"integrity/window/{src}",
                rr.SeriesLines(
                    colors=[colour, BOUND_COLOUR, BOUND_COLOUR],
                    names=[f"{src} window", f"{src} bounds", f"{src} bounds"],
                    widths=[1.5, 0.75, 0.75],
                ),
            )
        )
        out.append((f"state/source/{src}", state_configuration(STATES, STATE_COLOURS)))
    out.append(("state/overall", state_configuration(STATES, STATE_COLOURS)))
    for ch in CHANNEL_NAMES:
        out.append((f"state/channel/{ch}", state_configuration(CHANNEL_STATES, CHANNEL_STATE_COLOURS)))
    out.append(("integrity/vpl", rr.SeriesLines(colors=[VPL_COLOUR], names=["protection level"], widths=[2.0])))
    out.append(("integrity/alert_limit", rr.SeriesLines(colors=[ALERT_LIMIT_COLOUR], names=["alert limit"], widths=[1.5])))
    return out


def input_styles(group: str, kind: str) -> tuple[str, object]:
    """Style of an input-health series found while running (``group``: rate, rejected, gaps)."""
    colour = RATE_COLOURS.get(kind, RATE_COLOURS["imu"])
    entity = f"input/{group}/{kind}"
    if group == "rate":
        return entity, rr.SeriesLines(colors=[colour], names=[f"{kind} rate"], widths=[1.5])
    if group == "rejected":
        return entity, rr.SeriesLines(colors=[colour], names=[f"rejected {kind}"], widths=[1.5])
    return entity, rr.SeriesPoints(colors=[colour], names=[f"gap {kind}"], marker_sizes=[4.0])


def state_configuration(values, colours: dict[str, Rgb]) -> object:
    return rr.StateConfiguration(values=list(values), colors=[colours[v] for v in values])


# Legends cover the plot they explain (a third of it, in a corner that a
# climb, a hover or a spike will use sooner or later). Where the series are
# known in advance the view's title names their colours instead and the
# legend is hidden; the counters of rejected samples, whose kinds are found
# while running, keep a legend, top left (they count up from zero).
PILOT_TAB = "Pilot"
ENGINEERING_TAB = "Engineering"
PILOT_HEIGHTS = ("Height above home (m): fused dark cyan, its ±1σ band thin; GNSS blue, baro orange, "
                 "rangefinder purple (above ground) dots; autopilot pink")


def blueprint(live: bool, window_s: float = 30.0) -> rrb.Blueprint:
    """Two tabs (see the module docstring): the pilot's view, active, and the
    engineering panels.

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

    def series(name: str, contents, legend: bool = False, **kw) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(origin="/", contents=contents, name=name, time_ranges=ranges,
                                  plot_legend=rrb.PlotLegend(corner="LeftTop", visible=legend), **kw)

    def log_view(name: str, contents) -> rrb.TextLogView:
        return rrb.TextLogView(origin="/", contents=contents, name=name,
                               columns=rrb.TextLogColumns(text_log_columns=[
                                   rrb.encodings.TextLogColumn("EntityPath", visible=False), "LogLevel", "Body"]))

    # -- the pilot's tab
    readout = rrb.TextDocumentView(origin=READOUT, contents=[READOUT], name="Now")
    pilot_heights = series(PILOT_HEIGHTS, ["heights/fused", "heights/fused_sigma", "heights/raw/**",
                                           "heights/autopilot"])
    pilot_states = rrb.StateTimelineView(origin="/", contents=["state/overall", "state/source/**"], name="States",
                                         time_ranges=ranges)
    pilot_log = log_view("Alarms and events", ["alarms", "input/events"])
    # the state strip under the plot, the same width: their time axes line up
    pilot = rrb.Vertical(
        rrb.Horizontal(readout, rrb.Vertical(pilot_heights, pilot_states, row_shares=[5, 3]), column_shares=[1, 3]),
        pilot_log,
        row_shares=[4, 1],
        name=PILOT_TAB,
    )

    # -- the engineer's tab
    heights = series("All heights (m): channels lines, raw dots, refused crosses (colours as on the Pilot tab)",
                     ["heights/**"])
    pairs = series("Channel differences vs ±thresholds (m): gnss-rng teal, gnss-baro olive, rng-baro brown",
                   ["integrity/pairs/**"])
    nis = series("NIS, innovations: GNSS blue, rng purple, baro orange",
                 ["integrity/nis/**", "integrity/norm_innov/**"])
    window = series("Windows: GNSS blue, rng purple, baro orange, bounds grey",
                    ["integrity/window/**"])
    vpl = series("Protection level dark cyan, alert limit red (m)", ["integrity/vpl", "integrity/alert_limit"])
    states = rrb.StateTimelineView(origin="/", contents=["state/**"], name="All states", time_ranges=ranges)
    rates = series("Rates (Hz): IMU grey, baro, GNSS, rng", ["input/rate/**"])
    rejected = series("Rejected samples (count), gaps (s)", ["input/rejected/**", "input/gaps/**"], legend=True)
    events = log_view("Alarms and input events", ["alarms", "input/events"])
    engineering = rrb.Vertical(
        rrb.Horizontal(heights, pairs),
        rrb.Horizontal(nis, window, vpl),
        states,
        rrb.Horizontal(rates, rejected, events, column_shares=[1, 1, 2]),
        row_shares=[3, 2, 3, 2],
        name=ENGINEERING_TAB,
    )
    return rrb.Blueprint(
        rrb.Tabs(pilot, engineering, active_tab=0),  # the pilot's (by index: rerun names only views)
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE,
                      play_state="following" if live else None),
        auto_views=False,
    )
