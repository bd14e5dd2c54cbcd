"""The pilot's view in the Rerun viewer: one tab with the current height and state in
large type, the fused height with its band and the sensors, the state strip and the alarm
table; the engineering panels on a second tab; refused raw samples off the pilot's plot;
colours that read on the light and the dark theme; no legend over a plot.

A simulated GNSS step (config/scenarios/px4_hover_gnss_step.yaml) is replayed through the
pipeline into an .rrd, read back with rerun's own reader. The browser test
(tests/test_rerun_browser.py) shows the same flight in Chromium."""

from __future__ import annotations


import numpy as np
import pytest
import rerun.blueprint as rrb

from mavnav import pipeline
from mavnav.cli.viewer_options import make_viewer_sinks
from mavnav.config import Config
from mavnav.ingest import TlogSource
from mavnav.samples import GnssHeight
from mavnav.sinks import rerun_blueprint as bp
from mavnav.sinks.rerun_sink import READOUT_INTERVAL_S
from tests.support.rerun import Capture, read_rrd

HOVER_M = 15.0  # the scenario's hover height
STEP_M = 10.0  # its GNSS step
WHITE, DARK = (255, 255, 255), (13, 16, 17)  # the viewer's light and dark plot backgrounds


@pytest.fixture(scope="module")
def gnss_step(tmp_path_factory, simulated_tlog):
    tlog, res = simulated_tlog("px4_hover_gnss_step", 7)
    rrd = tmp_path_factory.mktemp("pilot") / "gnss_step.rrd"
    capture = Capture()
    sinks = make_viewer_sinks("none", None, str(rrd), live=False)
    summary = pipeline.run(TlogSource(tlog), Config(), [capture, *sinks], info={"source": "gnss_step"})
    assert not summary.sink_failures
    return capture, read_rrd(rrd), res.faults[0]


def _views(container):
    for c in container.contents:
        if isinstance(c, rrb.Container):
            yield from _views(c)
        else:
            yield c


def _matches(entity: str, patterns) -> bool:
    return any(entity == p or (p.endswith("/**") and entity.startswith(p[:-2])) for p in patterns)


def test_the_pilot_has_one_view_and_the_engineer_a_second_tab():
    for live in (False, True):
        root = bp.blueprint(live).root_container
        assert isinstance(root, rrb.Tabs) and [t.name for t in root.contents] == ["Pilot", "Engineering"]
        assert root.active_tab == 0
        pilot, eng = (list(_views(t)) for t in root.contents)
        kinds = {type(v).__name__: v for v in pilot}
        assert sorted(kinds) == ["StateTimelineView", "TextDocumentView", "TextLogView", "TimeSeriesView"]
        assert kinds["TextDocumentView"].contents == [bp.READOUT]
        heights = kinds["TimeSeriesView"].contents
        for entity in ("heights/fused", "heights/fused_sigma", "heights/raw/gnss", "heights/raw/baro",
                       "heights/raw/rangefinder", "heights/autopilot"):
            assert _matches(entity, heights), entity
        # nothing of the engineer's on the pilot's tab: refused samples, statistics, counters, channel lanes
        shown = [p for v in pilot for p in v.contents]
        for entity in ("heights/rejected/gnss", "heights/channel/gnss", "integrity/nis/gnss", "integrity/vpl",
                       "input/rejected/duplicate", "input/rate/imu", "state/channel/gnss"):
            assert not _matches(entity, shown), entity
        assert _matches("state/overall", shown) and _matches("state/source/gnss", shown)
        assert _matches("alarms", shown) and _matches("input/events", shown)
        # ... they are all on the engineering tab
        eng_shown = [p for v in eng for p in v.contents]
        for entity in ("heights/rejected/gnss", "integrity/pairs/gnss-rng/diff", "integrity/nis/gnss",
                       "integrity/window/gnss", "integrity/vpl", "input/rate/imu", "input/rejected/duplicate",
                       "state/channel/gnss"):
            assert _matches(entity, eng_shown), entity
        # no legend over a plot, but for the counters whose kinds are only known while running
        for v in pilot + eng:
            if isinstance(v, rrb.TimeSeriesView):
                legend = v.properties["PlotLegend"].visible.as_arrow_array().to_pylist()
                assert legend == [_matches("input/rejected/crc", v.contents)], v.name


def _luminance(c) -> float:
    def lin(v):
        v /= 255
        return v / 12.92 if v <= 0.03928 else ((v + 0.055) / 1.055) ** 2.4
    return 0.2126 * lin(c[0]) + 0.7152 * lin(c[1]) + 0.0722 * lin(c[2])


def contrast(a, b) -> float:
    """WCAG contrast ratio of two colours (1: none, 21: black on white)."""
    la, lb = sorted((_luminance(a), _luminance(b)))
    return (lb + 0.05) / (la + 0.05)


def test_every_series_reads_on_the_light_and_the_dark_theme():
    """Lines and dots at least 2:1 against both plot backgrounds (the fused line and the
    protection level used to be near-white, 1.2:1 on the light theme)."""
    colours = {}
    for entity, arch in bp.series_styles():
        if isinstance(arch, (bp.rr.SeriesLines, bp.rr.SeriesPoints)):
            for v in arch.colors.as_arrow_array().to_pylist():
                colours[(v >> 24 & 255, v >> 16 & 255, v >> 8 & 255)] = entity
    assert bp.FUSED_COLOUR in colours and bp.VPL_COLOUR in colours
    for c, entity in colours.items():
        assert contrast(c, WHITE) >= 2.0 and contrast(c, DARK) >= 2.0, (entity, c)
    assert contrast(bp.FUSED_COLOUR, WHITE) >= 3.0  # the pilot's line: like a graphic object (WCAG 1.4.11)


@pytest.mark.slow
def test_refused_raw_heights_stay_off_the_pilots_plot(gnss_step):
    capture, rec, fault = gnss_step
    onset, end = fault["onset_vehicle_s"], fault["onset_vehicle_s"] + fault["duration_s"]
    root = bp.blueprint(False).root_container
    pilot_plot = next(v for v in _views(root.contents[0]) if isinstance(v, rrb.TimeSeriesView))
    pilot = [e for e in rec.scalars if _matches(e, pilot_plot.contents)]
    assert {"heights/fused", "heights/raw/gnss", "heights/raw/baro", "heights/raw/rangefinder"} <= set(pilot)
    values = np.array([x for e in pilot for _, v in rec.scalars[e] for x in v])
    top = np.nanmax(values)
    assert top < HOVER_M + 5.0  # the plot spans the flight, not the step
    # the stepped GNSS samples are there, on the refused entity: while the GNSS was in alarm, all
    refused = rec.scalars["heights/rejected/gnss"]
    stepped = [v[0] for t, v in refused if onset + 2.0 <= t * 1e-9 <= end]
    during = [s for s in capture.samples if isinstance(s, GnssHeight) and onset + 2.0 <= s.t_us * 1e-6 <= end]
    assert len(stepped) == len(during) > 50
    assert min(stepped) > HOVER_M + STEP_M - 3.0
    # with them on the pilot's plot its range would be stretched by the step (the test can fail)
    assert max(stepped) > top + STEP_M / 2
    # and every GNSS sample is on one of the two entities, at its own vehicle time
    raw_t = [t for t, _ in rec.scalars["heights/raw/gnss"]] + [t for t, _ in refused]
    assert sorted(raw_t) == sorted(s.t_us * 1000 for s in capture.samples if isinstance(s, GnssHeight))


@pytest.mark.slow
def test_the_readout_says_height_and_state_in_large_type(gnss_step):
    capture, rec, _ = gnss_step
    docs = rec.docs[bp.READOUT]
    assert docs and all(m == "text/markdown" for _, _, m in docs)
    by_t = {t: text for t, text, _ in docs}
    # every change of a state has its readout at that epoch; the height and the state are headings
    prev = None
    changes = 0
    for r in capture.epochs:
        states = (r.overall, *(st.state for st in r.sources.values()))
        if states != prev:
            changes += 1
            text = by_t[r.t_us * 1000]
            lines = text.splitlines()
            h = r.height_fused_m
            assert lines[0] == (f"# {h:.1f} m" if h == h else "# no height")
            assert f"# {r.overall.upper()}" in lines
            for src, st in r.sources.items():
                if st.state != "nominal":
                    assert f"{bp.SOURCE_WORDS[src]} {st.state}**" in text
        prev = states
    assert changes > 5
    # between changes, a readout at least every READOUT_INTERVAL_S of vehicle time (one epoch late at most)
    times = np.array(sorted(by_t)) * 1e-9
    assert np.diff(times).max() <= READOUT_INTERVAL_S + 0.05
    assert len(docs) < len(capture.epochs) / 5  # not a document per epoch
    # in the GNSS alarm the pilot reads what is wrong and what to do
    alarm = [x for x in by_t.values() if "# ALARM" in x]
    assert alarm and all("**GNSS alarm**" in x and "Stop height-critical work" in x for x in alarm)
    # the last readout is at most that far behind the last epoch
    assert capture.epochs[-1].t_us * 1e-6 - times[-1] <= READOUT_INTERVAL_S
