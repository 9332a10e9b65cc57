"""python -m ik5r: the same command line as the ik5r script."""

import sys

from ik5r.tools.cli import main

sys.exit(main())
