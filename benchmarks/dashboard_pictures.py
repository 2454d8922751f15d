"""Renew the docs' pictures of the dashboard's pages from the browser tests that check them (issue 55).

Every page of ``coevo dashboard`` is opened in headless Chromium at 1280 x 800 by a test that checks what a screenshot
can (tests/pages.py: no error text, not blank, its title and headline in the DOM): a live run, a finished run, a
directory of runs, a comparison, a study and a study of learning runs, each on the tiny runs its test makes.  With
``COEVO_DASHBOARD_PICTURES=DIR`` each test also keeps its picture in DIR under the name the docs give it
(``dashboard.png``, ``dashboard-compare.png``, ...).  This runs those tests with DIR the docs folder, so the pictures
are renewed only from pages that passed their checks; a failing page leaves its old picture and the command fails.

    python benchmarks/dashboard_pictures.py [--out docs] [--python .venv/bin/python]

It needs Debian's chromium and chromium-driver (the tests skip without them: then nothing is renewed, and it says
so) and costs what the tests cost: a few minutes on 2 cores (a tiny comparison, a tiny study, a learning study).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The browser tests of the pages, and the pictures they keep.
TESTS = ["tests/test_dashboard.py::test_the_page_in_headless_chromium_follows_a_real_run",
         "tests/test_dashboard.py::test_a_comparison_opens_with_its_headline_above_the_fold_in_headless_chromium",
         "tests/test_dashboard.py::TestAStudyOnThePage",
         "tests/test_dashboard_pages.py::TestEveryPageInChromium"]
PICTURES = ["dashboard.png", "dashboard-compare.png", "dashboard-study.png", "dashboard-run.png", "dashboard-runs.png",
            "dashboard-learn-study.png"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs", help="where the pictures go (default: docs/)")
    ap.add_argument("--python", default=sys.executable, help="the Python of the venv coevo is installed in")
    args = ap.parse_args(argv)
    out = args.out.resolve()
    if not out.is_dir():
        print(f"--out {str(out)!r}: no such directory", file=sys.stderr)
        return 2
    before = {p: (out / p).stat().st_mtime_ns if (out / p).exists() else None for p in PICTURES}
    env = {**os.environ, "COEVO_DASHBOARD_PICTURES": str(out)}
    r = subprocess.run([args.python, "-m", "pytest", "-q", "--all", "-rs", *TESTS], cwd=ROOT, env=env, check=False)
    renewed = [p for p in PICTURES if (out / p).exists() and (out / p).stat().st_mtime_ns != before[p]]
    print(f"renewed {len(renewed)} of {len(PICTURES)} pictures in {out}: {', '.join(renewed) or 'none'}")
    return 0 if r.returncode == 0 and len(renewed) == len(PICTURES) else 1


if __name__ == "__main__":
    sys.exit(main())
