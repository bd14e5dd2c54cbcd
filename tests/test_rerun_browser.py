"""The web viewer in a real browser: a replay served on 127.0.0.1 (gRPC data
server + web viewer), opened in headless Chromium (WebGL on SwiftShader).

The test waits until the viewer has received every entity (read from the
viewer itself: its web handle encodes the recording it holds as RRD), then
screenshots the page and checks that the plots are drawn: the series'
colours are on screen in quantity, which a blank or loading page does not
show. Needs Debian's chromium at /usr/bin/chromium and the Python package
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

from mavnav import pipeline, synthetic
from mavnav.cli.viewer_options import make_viewer_sinks
from mavnav.sinks import rerun_blueprint as bp

from estimator_helpers import config_for
from test_rerun_sink import Capture, read_rrd

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


@pytest.mark.browser
def test_web_viewer_shows_the_replay_in_chromium(tmp_path):
    if not Path(CHROMIUM).exists() or shutil.which(CHROMIUM) is None:
        pytest.skip("Debian's chromium is not installed at /usr/bin/chromium (apt-get install -y chromium)")
    from PIL import Image
    from playwright.sync_api import sync_playwright

    said = []
    [sink] = make_viewer_sinks("web", None, None, live=False, web_port=0, grpc_port=0, viewer_hold=False,
                               echo=said.append)
    try:
        assert sink.page_url and said == [f"mavnav: Rerun web viewer at {sink.page_url}"]
        flight = synthetic.paper_flight(seed=3, schedule=synthetic.Schedule(duration_s=20.0))
        capture = Capture()
        # the filters told the simulated sensors' error model (the defaults
        # are sized on real baros, far quieter than the paper's sigma_bb 1 m):
        # a nominal flight, so the nominal lane is on screen
        cfg = config_for(synthetic.TrueSensors())
        summary = pipeline.run(flight.samples, cfg, [capture, sink], info={"source": "paper_flight(3)"})
        assert summary.sink_failures == {} and summary.epochs == 1000

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
                png = page.screenshot(path=str(SHOT_DIR / "mavnav_rerun_web.png"))
            finally:
                browser.close()
    finally:
        for proc in sink.processes:
            proc.stop()

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    assert rgb.shape[:2] == (1000, 1600)
    assert rgb.std() > 10, "blank screenshot"
    # the series are drawn: each sensor's colour covers many pixels (lines, points, lanes)
    for name, colour in (("baro", bp.CHANNEL_COLOURS["baro"]), ("gnss", bp.CHANNEL_COLOURS["gnss"]),
                         ("rangefinder", bp.CHANNEL_COLOURS["rangefinder"]),
                         ("nominal lane", bp.STATE_COLOURS["nominal"])):
        assert colour_pixels(rgb, colour) > 300, f"no {name} series on screen"
