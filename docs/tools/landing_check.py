"""Does the landing page fit one screen? A headless Chromium (Debian's ``chromium``) loads the built
``index.html`` at 1300 x 900, measures where its content ends and where its figure lies, and takes a
screenshot to look at.

    ./dev docs && .venv/bin/python docs/tools/landing_check.py     # -> docs/_build/landing.png

Prints the measurements; exit status 1 if the content or the figure reaches below the first screen
(or the figure did not load), 2 if Chromium or the built page is missing. The screen is the
viewport the page itself measures: Chromium 156's ``--dump-dom`` gives a 1300 x 900 window an
813 px high viewport (the screenshot is 900 px), so the check is the stricter of the two. Not run by the test
suite (Chromium is ~300 MB and not in packages.txt): a check for whoever edits docs/index.md.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

HTML = Path(__file__).resolve().parents[1] / "_build" / "html"
#: run on load, in the page itself: the lowest bottom edge of the article's visible blocks and the
#: figure's box, written into the DOM that --dump-dom prints
PROBE = """<script>
window.addEventListener("load", () => {
  const art = document.querySelector("article");
  const blocks = [...art.querySelectorAll("h1, p, figure, div.highlight, img")].filter(e => e.offsetParent);
  const img = art.querySelector("figure img");
  const r = img.getBoundingClientRect();
  const m = {viewport: [innerWidth, innerHeight], content_bottom: Math.max(...blocks.map(e => e.getBoundingClientRect().bottom)),
             figure: [r.left, r.top, r.width, r.height], figure_loaded: img.complete && img.naturalWidth > 0,
             page_height: document.documentElement.scrollHeight};
  const out = document.createElement("pre"); out.id = "landing-measure"; out.textContent = JSON.stringify(m);
  document.body.appendChild(out);
});
</script>"""


def chromium(*args: str, size: str = "1300,900") -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        raise SystemExit("landing_check: chromium not found (apt-get install chromium)")
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--window-size={size}",
           "--virtual-time-budget=5000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--html", type=Path, default=HTML, help="the built site (default docs/_build/html)")
    p.add_argument("--png", type=Path, default=HTML.parent / "landing.png", help="the screenshot")
    p.add_argument("--size", default="1300,900", help="window width,height in px (default 1300,900)")
    args = p.parse_args(argv)
    index = args.html / "index.html"
    if not index.is_file():
        print(f"landing_check: {index} not found (./dev docs first)", file=sys.stderr)
        return 2
    probe = args.html / "_landing_probe.html"     # beside index.html, so its relative links resolve
    probe.write_text(index.read_text().replace("</body>", PROBE + "</body>"))
    try:
        dom = chromium("--dump-dom", probe.as_uri(), size=args.size)
    finally:
        probe.unlink()
    chromium(f"--screenshot={args.png.resolve()}", index.as_uri(), size=args.size)
    found = re.search(r'<pre id="landing-measure">(.*?)</pre>', dom)
    if not found:
        print("landing_check: the page did not report its layout", file=sys.stderr)
        return 2
    m = json.loads(found.group(1).replace("&quot;", '"'))
    height = m["viewport"][1]
    x, y, w, h = m["figure"]
    fits = m["content_bottom"] <= height and y + h <= height and m["figure_loaded"]
    print(f"viewport {m['viewport'][0]} x {height}: content ends at {m['content_bottom']:.0f} px, figure "
          f"{w:.0f} x {h:.0f} px at y {y:.0f}-{y + h:.0f} ({'loaded' if m['figure_loaded'] else 'NOT loaded'}), "
          f"page height {m['page_height']} px -> {'fits one screen' if fits else 'does NOT fit one screen'}")
    print(f"screenshot: {args.png}")
    return 0 if fits else 1


if __name__ == "__main__":
    sys.exit(main())
