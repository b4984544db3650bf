"""Do the built site's code blocks fit their column? Measured in headless Chromium at a given window width.

For each page, a copy of its HTML (beside it, so its stylesheets load) gets a script that, once the page has laid
out, lists every ``pre > code`` block wider than its box (``scrollWidth > clientWidth``, which is what makes a
horizontal scroll bar) and every stylesheet or font requested from another host; Chromium's ``--dump-dom``
prints the result.

    python tools/docs_layout.py SITE_DIR tutorial/simple_task tutorial/component_tasks [--width 1280]

Exit status 1 when a block overflows or an external request is made. ``tests/test_docs_layout.py`` runs it on the
tutorial's pages when Chromium is installed.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

PROBE = """
<script>
window.addEventListener("load", () => {
  const blocks = [...document.querySelectorAll(".md-content pre > code")];
  const over = blocks.filter(c => c.scrollWidth > c.clientWidth + 1).map(c => ({
    first_line: c.innerText.split("\\n")[0].slice(0, 80), scroll: c.scrollWidth, box: c.clientWidth}));
  const external = performance.getEntriesByType("resource").map(r => r.name)
    .filter(n => /^https?:/.test(n) && !n.startsWith(location.origin));
  const widest = blocks.reduce((m, c) => Math.max(m, c.scrollWidth), 0);
  const box = blocks.length ? blocks[0].clientWidth : 0;
  const out = document.createElement("pre");
  out.id = "layout-report";
  out.textContent = JSON.stringify({blocks: blocks.length, overflowing: over, external, widest, box});
  document.body.appendChild(out);
});
</script>
"""
REPORT = re.compile(r'<pre id="layout-report">(.*?)</pre>', re.S)


def chromium() -> str | None:
    """The Chromium executable on this machine, if any."""
    return next(
        (found for name in ("chromium", "chromium-browser", "google-chrome") if (found := shutil.which(name))), None
    )


def measure(site: Path, page: str, width: int = 1280, browser: str | None = None) -> dict:
    """The layout report of ``page`` (``tutorial/simple_task``) of the built ``site`` at ``width`` px."""
    html = site / ("" if page == "index" else page) / "index.html"
    probe = html.with_name("_layout_probe.html")
    probe.write_text(html.read_text().replace("</body>", PROBE + "</body>"))
    try:
        proc = subprocess.run(
            [
                browser or chromium() or "chromium",
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                f"--window-size={width},900",
                "--virtual-time-budget=5000",
                "--dump-dom",
                probe.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    finally:
        probe.unlink()
    found = REPORT.search(proc.stdout)
    if not found:
        raise RuntimeError(f"no layout report from Chromium for {page}: {proc.stderr[-2000:]}")
    return {
        "page": page,
        "width": width,
        **json.loads(
            found.group(1).replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">")
        ),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="do the code blocks of built pages fit their column?")
    parser.add_argument("site")
    parser.add_argument("pages", nargs="+", help="pages of the site, e.g. tutorial/simple_task")
    parser.add_argument("--width", type=int, default=1280)
    args = parser.parse_args(argv)
    reports = [measure(Path(args.site), page, args.width) for page in args.pages]
    for report in reports:
        print(json.dumps(report))
    return 1 if any(r["overflowing"] or r["external"] for r in reports) else 0


if __name__ == "__main__":
    sys.exit(main())
