"""`python -m dvsot.cli`: the `dvsot` command."""

import sys

from dvsot.cli import main

sys.exit(main())
