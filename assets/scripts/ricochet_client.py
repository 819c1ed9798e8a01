#!/usr/bin/env python3
"""The `ricochet` Python package's command line, run from the repository without
installing it (it needs numpy and eclipse-zenoh: `bash .ci/install` puts both in its
virtual environment). `--help` lists the commands; python/src/ricochet/cli.py is the
code, docs/python.md the package."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "python" / "src"))

from ricochet.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
