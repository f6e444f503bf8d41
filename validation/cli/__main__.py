"""``python -m validation.cli``: the same as ``pillar-xval``."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())
