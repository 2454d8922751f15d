"""What a screenshot of a dashboard page can check (issue 55), for the browser tests of every page: opened at a
laptop's 1280 x 800, the page says no error, is not blank, and has its title and headline in the DOM.  A page's
picture is kept where ``COEVO_DASHBOARD_PICTURES`` names (a directory: benchmarks/dashboard_pictures.py sets it to
docs/ to renew the docs' pictures), under the name the docs give it."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path
from typing import Any

__all__ = ["WIDTH", "HEIGHT", "PAGE_FACTS", "open_page", "check_page", "blank_share"]

WIDTH, HEIGHT = 1280, 800

# The page as the browser holds it: its title, its headings and every text a reader sees (no script or style; Bokeh's
# Divs are in shadow roots),
# and the problems banner's own text
PAGE_FACTS = """
function deep(n) {
  let t = '';
  if (n.shadowRoot) t += deep(n.shadowRoot);
  for (const c of n.childNodes) {
    if (c.nodeType === 3) t += c.textContent + ' ';
    else if (c.nodeType === 1 && c.tagName !== 'SCRIPT' && c.tagName !== 'STYLE') t += deep(c);
  }
  return t;
}
function all(n, tag, out) {
  if (n.shadowRoot) all(n.shadowRoot, tag, out);
  for (const c of n.children || []) { if (c.tagName === tag) out.push(c.textContent.trim()); all(c, tag, out); }
  return out;
}
const doc = window.Bokeh && Bokeh.documents[0];
const banner = doc && doc.get_model_by_name('problems');
return {title: document.title, headings: all(document.body, 'H2', []), text: deep(document.body),
        problems: banner ? banner.text : null, viewport: [window.innerWidth, window.innerHeight],
        bokeh: !!doc};
"""

#: What no page may say: a Python error's name or traceback, a server error, a page Bokeh could not build.
ERROR_TEXT = re.compile(r"Traceback|\b\w*Error\b|Internal Server Error|500 Internal|is not defined|undefined")


def open_page(browser: Any, port: int) -> None:
    """The page at ``port`` on a 1280 x 800 screen."""
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
    browser.get(f"http://127.0.0.1:{port}/")


def blank_share(png: Path) -> float:
    """The share of a picture's pixels that are (near) white."""
    from matplotlib.image import imread

    rgb = imread(png)[..., :3]
    return float((rgb.min(axis=2) > 0.97).mean())


def check_page(browser: Any, shot: Path, *, picture: str, title: str, heading: str,
               headline: str | re.Pattern[str]) -> dict[str, Any]:
    """The page open in ``browser`` (:func:`open_page`), screenshotted to ``shot`` once ``headline`` is in its text:
    1280 x 800, ``title`` in the tab, ``heading`` its first heading (h2), ``headline`` in its text, no error text
    and an empty problems banner, and a picture that is not blank (under 97 % near-white pixels, several colours).
    Returns what the page held.  Kept as DIR/``picture`` when COEVO_DASHBOARD_PICTURES=DIR (the docs' name)."""
    from procs import poll

    pattern = headline if isinstance(headline, re.Pattern) else re.compile(re.escape(headline))
    facts = poll(lambda: (f := browser.execute_script(PAGE_FACTS)) and f["bokeh"] and pattern.search(f["text"]) and f,
                 60, lambda: f"the page's headline {pattern.pattern!r}: {browser.execute_script(PAGE_FACTS)['text'][:1500]}")
    browser.save_screenshot(str(shot))
    facts = browser.execute_script(PAGE_FACTS)
    assert facts["viewport"] == [WIDTH, HEIGHT], facts["viewport"]
    assert facts["title"] == title, (facts["title"], title)
    assert facts["headings"] and facts["headings"][0] == heading, (facts["headings"], heading)
    said = ERROR_TEXT.search(facts["text"])
    assert said is None, f"the page says {said.group(0)!r}: {facts['text'][max(0, said.start() - 300):said.end() + 300]}"
    assert not facts["problems"], facts["problems"]
    white = blank_share(shot)
    assert white < 0.97, f"{shot}: {white:.1%} of the picture is white"
    from matplotlib.image import imread

    colours = {tuple(p) for p in (imread(shot)[..., :3] * 16).astype(int).reshape(-1, 3)[::97]}
    assert len(colours) > 20, f"{shot}: only {len(colours)} colours"
    where = os.environ.get("COEVO_DASHBOARD_PICTURES")
    if where:
        shutil.copy(shot, Path(where) / picture)
    return facts
