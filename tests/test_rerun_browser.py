"""The web viewer in a real browser: a fault flight (a simulated GNSS step) replayed
and served on 127.0.0.1 (gRPC data server + web viewer), opened in headless
Chromium (WebGL on SwiftShader).

The test waits until the viewer has received every entity (read from the
viewer itself: its web handle encodes the recording it holds as RRD), then
screenshots the page and checks that the pilot's tab is drawn: the fused
line, the sensors' dots and the alarm in the state strip are on screen in
quantity, which a blank or loading page does not show. The screenshot is
kept (``$MAVNAV_SCREENSHOT_DIR``, default /tmp) for a person to look at.
Needs Debian's chromium at /usr/bin/chromium and the Python package
playwright.
"""

from __future__ import annotations

import base64
import io
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from mavnav import pipeline
from mavnav.cli.viewer_options import make_viewer_sinks
from mavnav.config import Config
from mavnav.ingest import TlogSource
from mavnav.sinks import rerun_blueprint as bp

from tests.support.rerun import Capture, read_rrd

pytestmark = [pytest.mark.integration, pytest.mark.slow]

CHROMIUM = "/usr/bin/chromium"
FLAGS = [
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
]
SHOT_DIR = Path(os.environ.get("MAVNAV_SCREENSHOT_DIR", "/tmp"))

# The viewer's own copy of the recording, as RRD bytes, base64 (chunked: large arrays).
SAVE_JS = """() => {
  const h = window._handle;
  if (!h) return null;
  let bytes;
  try { bytes = h.save_recording(); } catch (e) { return null; }
  let s = "";
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
}"""

EXPECTED = {
    "pilot/readout", "heights/rejected/gnss",
    "heights/fused", "heights/fused_sigma", "heights/raw/baro", "heights/raw/gnss", "heights/raw/rangefinder",
    *(f"heights/channel/{c}" for c in ("gnss", "rangefinder", "baro")),
    *(f"integrity/pairs/{p}/{w}" for p in ("gnss-rng", "gnss-baro", "rng-baro") for w in ("diff", "threshold")),
    *(f"integrity/nis/{c}" for c in ("gnss", "rangefinder", "baro")),
    "integrity/vpl", "integrity/alert_limit", "alarms",
    *(f"state/source/{s}" for s in ("gnss", "rangefinder", "baro_ins", "input")), "state/overall",
    *(f"input/rate/{k}" for k in ("imu", "baro", "gnss", "range")),
}


def colour_pixels(rgb: np.ndarray, colour, tol: int = 40) -> int:
    return int((np.abs(rgb.astype(int) - np.array(colour)).max(axis=2) <= tol).sum())


def on_white(colour, alpha: float):
    """What ``colour`` drawn with opacity ``alpha`` looks like on the light theme's white."""
    return tuple(alpha * c + (1 - alpha) * 255 for c in colour)


LANE_OPACITY = 0.8  # the viewer draws state lanes a little see-through (measured on its screenshots)


@pytest.mark.browser
def test_web_viewer_shows_the_pilot_a_fault_flight_in_chromium(tmp_path, simulated_tlog):
    if not Path(CHROMIUM).exists() or shutil.which(CHROMIUM) is None:
        pytest.skip("Debian's chromium is not installed at /usr/bin/chromium (apt-get install -y chromium)")
    from PIL import Image
    from playwright.sync_api import sync_playwright

    said = []
    [sink] = make_viewer_sinks("web", None, None, live=False, web_port=0, grpc_port=0, viewer_hold=False,
                               echo=said.append)
    try:
        assert sink.page_url and said == [f"mavnav: Rerun web viewer at {sink.page_url}"]
        tlog, _ = simulated_tlog("px4_hover_gnss_step", 7)
        capture = Capture()
        summary = pipeline.run(TlogSource(tlog), Config(), [capture, sink], info={"source": tlog.name})
        assert summary.sink_failures == {} and summary.epochs > 1000
        assert any(e.source == "gnss" and e.state == "alarm" for e in capture.alarms)

        with sync_playwright() as p:
            # launch() runs Chromium on a fresh temporary profile (a new --user-data-dir)
            browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
            try:
                page = browser.new_page(viewport={"width": 1600, "height": 1000})
                page.goto(sink.page_url)
                deadline = time.monotonic() + 60
                held = None
                while time.monotonic() < deadline:
                    time.sleep(2)
                    data = page.evaluate(SAVE_JS)
                    if not data:
                        continue
                    (tmp_path / "viewer.rrd").write_bytes(base64.b64decode(data))
                    try:
                        held = read_rrd(tmp_path / "viewer.rrd")
                    except ValueError:  # no recording store yet (only the blueprint has arrived)
                        continue
                    if EXPECTED <= held.data_entities and len(held.scalars["heights/fused"]) == summary.epochs:
                        break
                assert held is not None, "the viewer never started (no web handle)"
                missing = EXPECTED - held.data_entities
                assert not missing, f"the viewer lacks {sorted(missing)}"
                assert len(held.scalars["heights/fused"]) == summary.epochs
                assert [t for t, _, _ in held.texts["alarms"]] == [e.t_us * 1000 for e in capture.alarms]

                time.sleep(3)  # let SwiftShader draw a few frames of the loaded data
                png = page.screenshot(path=str(SHOT_DIR / "mavnav_rerun_pilot.png"))
            finally:
                browser.close()
    finally:
        for proc in sink.processes:
            proc.stop()

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    assert rgb.shape[:2] == (1000, 1600)
    assert rgb.std() > 10, "blank screenshot"
    # the pilot's tab is drawn: the fused line, the sensors' dots, the alarm in the state strip
    dots = bp.RAW_ALPHA / 255
    for name, colour, least in (("fused line", bp.FUSED_COLOUR, 1000),
                                ("baro dots", on_white(bp.CHANNEL_COLOURS["baro"], dots), 200),
                                ("GNSS dots", on_white(bp.CHANNEL_COLOURS["gnss"], dots), 200),
                                ("alarm lane", on_white(bp.STATE_COLOURS["alarm"], LANE_OPACITY), 2000),
                                ("nominal lane", on_white(bp.STATE_COLOURS["nominal"], LANE_OPACITY), 2000)):
        assert colour_pixels(rgb, colour, tol=25) > least, f"no {name} on screen"
