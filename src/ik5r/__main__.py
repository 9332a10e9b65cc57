"""python -m ik5r: the same command line as the ik5r script."""

import sys

from .tools.cli import main

sys.exit(main())
