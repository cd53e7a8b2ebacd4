"""The report renders in a real browser: headless Chromium opens a lab's analysed run folder and every image of
its ``index.html`` decodes. ``make validate`` installs Chromium from the Debian packages where it is missing."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Headless, and quiet on a machine without a network (no background connections, no first-run pages).
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--virtual-time-budget=20000", "--dump-dom")
#: Appended to a copy of the report: after loading, the body records how many images there are and how many did
#: not decode (an image that fails to decode has no natural width).
PROBE = ("<script>window.addEventListener('load', () => { const i = [...document.images];"
         " document.body.setAttribute('data-images', i.length);"
         " document.body.setAttribute('data-broken', i.filter(x => !(x.complete && x.naturalWidth > 0)).length);"
         " });</script>")


def rendered(html_path: Path, profile: Path) -> tuple[int, int]:
    """(images, images that did not decode) of ``html_path`` as Chromium renders it."""
    probe = html_path.with_name("probe.html")
    probe.write_text(html_path.read_text().replace("</body>", PROBE + "</body>"))
    done = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", probe.as_uri()], capture_output=True,
                          text=True, timeout=300)
    m = re.search(r'data-images="(\d+)" data-broken="(\d+)"', done.stdout)
    assert m, done.stderr[-2000:]
    return int(m.group(1)), int(m.group(2))


@pytest.mark.validation
def test_every_image_of_the_report_renders_in_chromium(tmp_path):
    if CHROMIUM is None:
        pytest.fail("chromium is not installed (make validate installs the Debian package chromium)")
    from scioc.pipelines.run import analyse_to_dir

    report = analyse_to_dir(ROOT / "data" / "examples" / "lab-export", tmp_path / "run")
    images, broken = rendered(report, tmp_path / "profile")
    assert images == report.read_text().count("<img ") >= 3 and broken == 0
    # Negative control: one image's data cut short does not decode, and the probe counts it.
    html = report.read_text()
    start = html.index("data:image/png;base64,") + len("data:image/png;base64,")
    bad = tmp_path / "bad" / "index.html"
    bad.parent.mkdir()
    bad.write_text(html[:start] + "AAAA" + html[start + 400:])
    assert rendered(bad, tmp_path / "profile2") == (images, 1)
