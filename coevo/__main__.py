from __future__ import annotations

import sys

from coevo.cli import main

sys.exit(main())
