"""``python -m stcvision`` runs the CLI."""

import sys

from stcvision.cli import main

sys.exit(main())
