"""The report page in a real browser: headless Chromium renders `index.html` and decodes every figure.

A copy of the page gets a small script that, in the window's load event, draws every ``<img>`` on a
canvas (a full decode; pixels of a PNG that does not decode stay transparent), measures it and
writes the result as JSON into the DOM; ``chromium --dump-dom`` prints that DOM.

Needs Debian's ``chromium`` (``apt-get install chromium``; CI installs it with ``.ci/install-chromium``).
Without it the tests skip, unless ``REFEXMC_REQUIRE_CHROMIUM=1`` (set by ``.ci/run``): then they fail.
"""

import base64
import contextlib
import html
import json
import os
import re
import shutil
import signal
import struct
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from stored import store_campaign

from refexmc.config.load import apply_overrides, load_campaign
from refexmc.report import make_report

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM_TIMEOUT_S = 90
WINDOW = (1300, 1600)
FLAGS = (
    "--headless",
    "--no-sandbox",  # the tests may run as root (CI)
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    # no network traffic of its own: on a closed network these stall or fail the launch
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    f"--window-size={WINDOW[0]},{WINDOW[1]}",
)
PROBE_ID = "refexmc-render-probe"
PROBE = f"""
<script>
// runs synchronously in the load event (which waits for every image), so --dump-dom sees its result
window.addEventListener("load", () => {{
  const images = Array.from(document.images);
  const pixels = images.map((img) => {{
    // drawing forces a full decode; a figure that does not decode leaves transparent pixels
    const canvas = document.createElement("canvas");
    canvas.width = img.naturalWidth;
    canvas.height = img.naturalHeight;
    if (!canvas.width || !canvas.height) return {{opaque: 0, inked: 0}};
    const context = canvas.getContext("2d");
    context.drawImage(img, 0, 0);
    const rgba = context.getImageData(0, 0, canvas.width, canvas.height).data;
    let opaque = 0, inked = 0;
    for (let i = 0; i < rgba.length; i += 4) {{
      if (rgba[i + 3] === 255) opaque++;
      if (rgba[i + 3] > 0 && rgba[i] + rgba[i + 1] + rgba[i + 2] < 600) inked++;
    }}
    const n = rgba.length / 4;
    return {{opaque: opaque / n, inked: inked / n}};
  }});
  const verdict = document.querySelector(".verdict");
  const probe = {{
    images: images.length,
    complete: images.map((img) => img.complete && img.naturalWidth > 0),
    natural: images.map((img) => [img.naturalWidth, img.naturalHeight]),
    shown: images.map((img) => [img.getBoundingClientRect().width, img.getBoundingClientRect().height]),
    opaque: pixels.map((p) => p.opaque),
    inked: pixels.map((p) => p.inked),
    alts: images.map((img) => img.alt),
    title: document.title,
    h1: Array.from(document.querySelectorAll("h1"), (h) => h.innerText),
    h2: Array.from(document.querySelectorAll("h2"), (h) => h.innerText),
    verdict: verdict ? verdict.innerText : null,
    verdict_background: verdict ? getComputedStyle(verdict).backgroundColor : null,
    page_height: document.documentElement.scrollHeight,
  }};
  const out = document.createElement("pre");
  out.id = "{PROBE_ID}";
  out.textContent = JSON.stringify(probe);
  document.body.appendChild(out);
}});
</script>
"""
DATA_URI = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]*)"')


@pytest.fixture(scope="module")
def chromium():
    path = shutil.which("chromium")
    if path is None:
        reason = "the render test needs Debian's chromium on PATH (apt-get install chromium; CI: .ci/install-chromium)"
        if os.environ.get("REFEXMC_REQUIRE_CHROMIUM") == "1":
            pytest.fail(f"{reason}; REFEXMC_REQUIRE_CHROMIUM=1 does not allow skipping")
        pytest.skip(reason)
    return path


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A small real campaign (smoke.yaml, 12 runs, random single failures) and its HTML report."""
    campaign = apply_overrides(load_campaign(ROOT / "campaigns/smoke.yaml"), runs=12)
    campaign["failures"] = {"mode": "random", "count_probabilities": [0.4, 0.6]}
    out = tmp_path_factory.mktemp("render") / "out"
    store_campaign(campaign, out)
    result = make_report(out, html=True)
    page = (out / "report" / "index.html").read_text()
    return out, result["summary"], page


def run_chromium(binary, workdir, *arguments):
    """Run headless Chromium with a fresh profile under ``workdir``; its stdout. Fails on a timeout or exit != 0."""
    profile = tempfile.mkdtemp(prefix="chromium-profile-", dir=workdir)
    command = [binary, *FLAGS, f"--user-data-dir={profile}", *arguments]
    # its own session, so that a timeout ends the renderer and zygote processes too
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=CHROMIUM_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        stdout, stderr = proc.communicate()
        pytest.fail(f"chromium did not finish within {CHROMIUM_TIMEOUT_S} s; stderr tail:\n{stderr[-3000:]}")
    finally:
        with contextlib.suppress(ProcessLookupError):  # helpers it may have left behind (its own group only)
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, f"chromium exited with {proc.returncode}; stderr tail:\n{stderr[-3000:]}"
    return stdout


def probe(binary, page, workdir):
    """Render ``page`` (HTML text) with the probe script appended; the probe's JSON result."""
    assert page.count("</body>") == 1
    path = Path(tempfile.mkdtemp(prefix="page-", dir=workdir)) / "index.html"
    path.write_text(page.replace("</body>", PROBE + "</body>"))
    # the probe runs inside the load event, before the dump; the virtual time budget lets the page settle first
    dom = run_chromium(binary, workdir, "--virtual-time-budget=10000", "--dump-dom", path.as_uri())
    found = re.search(rf'<pre id="{PROBE_ID}">(.*?)</pre>', dom, re.S)
    assert found, f"the probe did not report (page not loaded?); DOM dump starts:\n{dom[:2000]}"
    return json.loads(html.unescape(found.group(1)))


def png_size(payload):
    """(width, height) from the IHDR chunk of base64 PNG ``payload``."""
    head = base64.b64decode(payload[:64])
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    return list(struct.unpack(">II", head[16:24]))


def figures_drawn(result):
    """Per figure: the browser loaded it and drew every pixel of it (a figure is opaque), with some ink on it."""
    return [
        complete and opaque == 1 and inked > 0.01
        for complete, opaque, inked in zip(result["complete"], result["opaque"], result["inked"], strict=True)
    ]


def test_page_renders_and_every_figure_decodes(chromium, report, tmp_path):
    _, summary, page = report
    titles = summary["figures"]
    payloads = DATA_URI.findall(page)
    assert len(titles) >= 5  # modes, propellant, failure sets (and matrix), sensitivity, convergence
    assert len(payloads) == len(titles) == page.count("<img")
    result = probe(chromium, page, tmp_path)
    assert result["images"] == len(titles)
    assert figures_drawn(result) == [True] * len(titles), result
    # the browser decoded the very PNGs of the page, and laid each out with a size
    assert result["natural"] == [png_size(p) for p in payloads]
    assert all(w > 100 and h > 100 for w, h in result["shown"]), result["shown"]
    assert result["alts"] == titles
    name = summary["campaign"]["name"]
    assert result["title"] == f"refexmc report: {name}"
    assert result["h1"] == [f"Campaign {name}"]
    headings = ["Requirements", "Success", "Failure reasons", "Other outputs over the successful flights", *titles]
    for heading in [*headings, "Worst cases"]:
        assert heading in result["h2"], f"heading {heading!r} not rendered; rendered: {result['h2']}"
    met = sum(r["passed"] for r in summary["requirements"])
    assert summary["verdict"] in ("PASS", "FAIL")  # stored whole, no errored run: a verdict
    assert result["verdict"].startswith(summary["verdict"])
    assert f"{met} of {len(summary['requirements'])} requirements met" in result["verdict"]
    assert result["verdict_background"] not in ("rgba(0, 0, 0, 0)", "transparent")  # the inline CSS applied
    assert result["page_height"] > WINDOW[1]


def test_probe_reports_corrupted_figures(chromium, report, tmp_path):
    """The check can fail: a truncated PNG and one with garbled pixel data (headers intact) are caught.

    (Chromium 150 still calls both images ``complete``, with their full size: only drawing them shows it.)
    """
    _, _, page = report
    payloads = DATA_URI.findall(page)
    assert len(payloads) >= 4
    truncated, garbled = 1, 3
    corrupt = {
        truncated: lambda data: data[: len(data) // 2],
        garbled: lambda data: data[:2000] + bytes(b ^ 0xFF for b in data[2000:2100]) + data[2100:],
    }
    for k, damage in corrupt.items():
        data = base64.b64decode(payloads[k])
        page = page.replace(payloads[k], base64.b64encode(damage(data)).decode("ascii"))
    result = probe(chromium, page, tmp_path)
    assert result["images"] == len(payloads)
    assert figures_drawn(result) == [k not in corrupt for k in range(len(payloads))], result


def test_screenshot_is_not_blank(chromium, report, tmp_path):
    from matplotlib import image

    out, _, _ = report
    shot = tmp_path / "page.png"
    run_chromium(chromium, tmp_path, f"--screenshot={shot}", (out / "report" / "index.html").as_uri())
    pixels = image.imread(shot)[..., :3]
    assert pixels.shape[:2] == (WINDOW[1], WINDOW[0])
    gray = pixels.mean(axis=2)
    assert (gray < 0.9).mean() > 0.01, "the screenshot is (almost) all white"
    assert len(np.unique(np.round(gray * 255))) > 16  # text, table borders, the colored verdict
